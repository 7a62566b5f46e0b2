"""Cell-linked-list neighbour search against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph.neighbours import RADIUS_TOLERANCE, NeighbourList, brute_force_pairs


def pairs_of(nl: NeighbourList) -> set[tuple[int, int]]:
    return nl.pairs()


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_random_points(dim):
    rng = np.random.default_rng(dim)
    x = rng.random((400, dim)) * [1.0, 0.7, 0.5][:dim]
    radius = 0.13
    nl = NeighbourList.build(x, radius)
    assert pairs_of(nl) == brute_force_pairs(x, radius)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_lattice_with_points_on_cell_borders(dim):
    """A lattice whose spacing divides the cell size: many points sit exactly on cell borders
    and many pair distances equal the radius (those must be excluded: r < radius)."""
    dx = 0.25
    n = {1: 40, 2: 12, 3: 6}[dim]
    axis = np.arange(n) * dx
    x = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    for radius in (0.5, 0.5 + 1e-12, 0.6):
        nl = NeighbourList.build(x, radius)
        assert pairs_of(nl) == brute_force_pairs(x, radius)


def test_negative_coordinates_and_single_particle():
    x = np.array([[-3.0, -2.0], [-2.9, -2.0], [5.0, 5.0]])
    assert pairs_of(NeighbourList.build(x, 0.2)) == {(0, 1), (1, 0)}
    one = NeighbourList.build(np.zeros((1, 3)), 1.0)
    assert one.n_pairs == 0


def test_skin_triggers_rebuild():
    x = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0), indexing="ij"), -1).reshape(-1, 2)
    nl = NeighbourList.build(x, support=1.5, skin=0.4)
    assert not nl.stale(x + 0.1, 1.5)  # moved 0.14 < skin / 2
    moved = x.copy()
    moved[3] += 0.25
    assert nl.stale(moved, 1.5)
    nl.update(moved, support=1.5)
    assert nl.builds == 2
    assert pairs_of(nl) == brute_force_pairs(moved, 1.9)


def test_support_growing_past_the_radius_makes_the_list_stale():
    """The list holds pairs within support + skin of the build: a larger support needs a new
    list even if nothing has moved; a recomputed equal support (round-off) does not."""
    x = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0), indexing="ij"), -1).reshape(-1, 2)
    nl = NeighbourList.build(x, support=1.5, skin=0.4)
    assert not nl.stale(x, 1.5)
    assert not nl.stale(x, 1.5 * (1 + RADIUS_TOLERANCE / 10))
    assert nl.stale(x, 1.5 * (1 + 10 * RADIUS_TOLERANCE))
    assert nl.stale(x, 1.6)
    assert not nl.stale(x, 1.0)  # a smaller support is covered
    nl.update(x, support=1.6)
    assert nl.builds == 2 and nl.radius == pytest.approx(2.0)
    assert pairs_of(nl) == brute_force_pairs(x, 2.0)
    assert NeighbourList.build(x, support=1.5).stale(x, 1.5)  # no skin: always rebuilt
