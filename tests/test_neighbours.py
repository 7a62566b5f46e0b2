"""Cell-linked-list neighbour search against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph.neighbours import (
    RADIUS_TOLERANCE,
    NeighbourList,
    brute_force_pairs,
    inner_entries_first,
)


def pairs_of(nl: NeighbourList) -> set[tuple[int, int]]:
    return nl.pairs()


def inner_entries(nl: NeighbourList) -> np.ndarray:
    """Every row's inner entries (``indices[offsets[p]:inner_ends[p]]``), row after row."""
    starts = nl.offsets[:-1]
    return np.concatenate([nl.indices[a:b] for a, b in zip(starts, nl.inner_ends, strict=True)]
                          + [np.zeros(0, nl.indices.dtype)])


def inner_pairs(nl: NeighbourList) -> set[tuple[int, int]]:
    """The ordered pairs ``(i, j)`` of particle numbers of the inner list."""
    rows = np.repeat(nl.order, nl.inner_ends - nl.offsets[:-1])
    cols = nl.order[inner_entries(nl)]
    return set(zip(rows.tolist(), cols.tolist(), strict=True))


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


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_the_displacement_check_in_shares_finds_the_one_particle_past_half_the_skin(
        dim, monkeypatch):
    """The list's displacement check runs in shares on numba's threads from
    ``DISPLACEMENT_SHARE_ROWS`` rows a share: in three shares (whatever this worker's thread
    count) the largest displacement is the serial check's to the bit, wherever the one
    particle that moved farthest sits (first row, a share's first and last rows, last row),
    and ``stale`` says so in shares as it does serially."""
    import impactsph.neighbours as neighbours
    from impactsph.physics.chunked import run_chunked

    _, serial, share = neighbours._build_functions(dim)
    rng = np.random.default_rng(7 + dim)
    side = {1: 900, 2: 30, 3: 10}[dim]
    x0 = np.stack(np.meshgrid(*[np.arange(float(side))] * dim, indexing="ij"),
                  -1).reshape(-1, dim)
    n = x0.shape[0]
    nl = NeighbourList.build(x0, support=1.5, skin=0.4)
    for row in (0, n // 3 - 1, n // 3, 2 * n // 3, n - 1):
        x = x0 + rng.uniform(-0.1, 0.1, x0.shape)  # each |d| < 0.18 < skin / 2
        x[row] = x0[row] + 0.21 / np.sqrt(dim)  # |d| = 0.21: past skin / 2
        reference = nl.reference_positions
        largest = np.full(3, -1.0)
        run_chunked(share, 3, x, reference, nl.reference_origin, largest)
        assert (largest >= 0.0).all()
        assert np.sqrt(largest.max()) == serial(x, reference, nl.reference_origin)
        assert 0.2 < serial(x, reference, nl.reference_origin) < 0.22
        monkeypatch.setattr(neighbours, "DISPLACEMENT_SHARE_ROWS", n // 3)
        monkeypatch.setattr(neighbours, "numba_threads", lambda: 3)
        assert nl.stale(x, 1.5)
        x[row] = x0[row] + 0.19 / np.sqrt(dim)  # now within skin / 2: not stale
        assert not nl.stale(x, 1.5)
        monkeypatch.undo()
        assert not nl.stale(x, 1.5)


def test_the_range_of_the_smoothing_lengths_is_numpys_min_and_max():
    """``solver.value_range`` keeps four running pairs over interleaved values: for every
    length 1-13 (each remainder of four) and the extremes at every place, its ``(smallest,
    largest)`` is numpy's; an empty array is refused."""
    from impactsph.solver import value_range

    rng = np.random.default_rng(11)
    for n in range(1, 14):
        for place in range(n):
            values = rng.uniform(1.0, 2.0, n)
            values[place] = 0.5
            values[n - 1 - place] = 3.0 if n > 1 else 0.5
            assert value_range(values) == (values.min(), values.max())
    with pytest.raises(ValueError, match="empty"):
        value_range(np.zeros(0))


def test_rank_is_the_inverse_of_the_order_and_follows_each_rebuild():
    """``rank`` (the particle pass writes particle i's record to row ``rank[i]``) is the
    inverse permutation of ``order``, made once per build and made again after a rebuild."""
    rng = np.random.default_rng(4)
    x = rng.random((300, 2))
    nl = NeighbourList.build(x, support=0.12, skin=0.02)
    assert not np.array_equal(nl.order, np.arange(300))  # a real permutation
    rank = nl.rank
    assert rank.dtype == nl.order.dtype
    assert np.array_equal(rank[nl.order], np.arange(300))
    assert np.array_equal(nl.order[rank], np.arange(300))
    assert nl.rank is rank  # made once per build
    moved = x + rng.normal(0.0, 0.05, x.shape)
    nl.update(moved, support=0.12)
    assert nl.builds == 2
    assert np.array_equal(nl.rank[nl.order], np.arange(300))
    assert not np.array_equal(nl.rank, rank)  # the new build's order, not the old one's


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


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_inner_list_is_the_near_part_of_each_row_at_its_start(dim):
    """The inner list is, for each particle, exactly the pairs closer than ``reach * support
    + skin``: its row's first entries, in the order they have in the list built without an
    inner list, whose row follows them without them (its front part and its back part as
    there: the same splits)."""
    rng = np.random.default_rng(10 + dim)
    x = rng.random((500, dim)) * [1.0, 0.7, 0.5][:dim]
    support, skin, reach = 0.12, 0.012, 0.5
    nl = NeighbourList.build(x, support, skin, inner_reach=reach)
    assert nl.inner_reach == reach
    assert nl.inner_radius == pytest.approx(reach * support + skin)
    assert inner_pairs(nl) == brute_force_pairs(x, reach * support + skin)
    assert nl.inner_ends.dtype == nl.offsets.dtype == np.int32
    whole = NeighbourList.build(x, support, skin)
    assert whole.inner_ends is None
    np.testing.assert_array_equal(nl.order, whole.order)
    np.testing.assert_array_equal(nl.offsets, whole.offsets)
    if dim > 1:
        np.testing.assert_array_equal(nl.splits, whole.splits)
    xs = x[nl.order]
    inner_sizes = []
    for p in range(x.shape[0]):
        row = whole.indices[whole.offsets[p]:whole.offsets[p + 1]]
        near = np.linalg.norm(xs[row] - xs[p], axis=1) < nl.inner_radius
        assert nl.offsets[p] <= nl.inner_ends[p] <= nl.offsets[p + 1]
        np.testing.assert_array_equal(nl.indices[nl.offsets[p]:nl.inner_ends[p]], row[near])
        np.testing.assert_array_equal(nl.indices[nl.inner_ends[p]:nl.offsets[p + 1]],
                                      row[~near])
        inner_sizes.append(int(near.sum()))
    assert 0 < np.mean(inner_sizes) < 0.6 * np.mean(np.diff(nl.offsets))  # a part, not all
    # a reach the inner list covers gets its ends; a longer one the rows' own ends, a view of
    # the offsets (the same object while they are the same array)
    assert nl.within(reach) is nl.inner_ends
    assert nl.within(0.3) is nl.inner_ends
    ends = nl.within(0.6)
    np.testing.assert_array_equal(ends, nl.offsets[1:])
    assert ends.base is nl.offsets and nl.within(1.0) is ends
    # without a reach below 1 there is none
    np.testing.assert_array_equal(whole.within(0.5), whole.offsets[1:])
    with pytest.raises(ValueError, match="inner_reach = 0.0"):
        NeighbourList.build(x, support, skin, inner_reach=0.0)
    with pytest.raises(ValueError, match=r"inner_ends of shape \(3,\)"):
        NeighbourList(nl.offsets, nl.indices, nl.radius, skin, nl.reference_positions,
                      inner_reach=reach, inner_radius=nl.inner_radius,
                      inner_ends=nl.inner_ends[:3])
    beyond = nl.inner_ends.copy()
    beyond[7] = nl.offsets[8] + 1  # (past its row's end: the pass would read the next row)
    with pytest.raises(ValueError, match="one per row .* within the row"):
        NeighbourList(nl.offsets, nl.indices, nl.radius, skin, nl.reference_positions,
                      inner_reach=reach, inner_radius=nl.inner_radius, inner_ends=beyond)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_an_inner_list_of_its_own_is_moved_to_the_rows_starts(dim):
    """A list held with an inner list of its own (as before 2026-12-07, and in checkpoints
    of then), each row's inner entries moved to its start by ``inner_entries_first``, is the
    list a build now makes."""
    rng = np.random.default_rng(30 + dim)
    x = rng.random((400, dim)) * [1.0, 0.7, 0.5][:dim]
    support, skin, reach = 0.12, 0.012, 0.5
    nl = NeighbourList.build(x, support, skin, inner_reach=reach)
    whole = NeighbourList.build(x, support, skin)
    # the old layout: the whole list's rows, and the inner entries in their order apart
    xs = x[whole.order]
    inner_offsets, inner_indices = [0], []
    for p in range(x.shape[0]):
        row = whole.indices[whole.offsets[p]:whole.offsets[p + 1]]
        near = row[np.linalg.norm(xs[row] - xs[p], axis=1) < nl.inner_radius]
        inner_indices.extend(near.tolist())
        inner_offsets.append(len(inner_indices))
    moved, inner_ends = inner_entries_first(whole.offsets, whole.indices,
                                            np.array(inner_offsets, dtype=np.int32),
                                            np.array(inner_indices, dtype=np.int32))
    assert moved.dtype == nl.indices.dtype and inner_ends.dtype == nl.inner_ends.dtype
    np.testing.assert_array_equal(moved, nl.indices)
    np.testing.assert_array_equal(inner_ends, nl.inner_ends)
    # an inner row that is not a part of its row, in its order, is refused
    swapped = np.array(inner_indices, dtype=np.int32)
    first = next(p for p in range(x.shape[0]) if inner_offsets[p + 1] - inner_offsets[p] > 1)
    a = inner_offsets[first]
    swapped[a], swapped[a + 1] = swapped[a + 1], swapped[a]
    with pytest.raises(ValueError, match="not a part of its row"):
        inner_entries_first(whole.offsets, whole.indices,
                            np.array(inner_offsets, dtype=np.int32), swapped)


def test_inner_list_is_rebuilt_with_the_list():
    x = np.stack(np.meshgrid(np.arange(6.0), np.arange(6.0), indexing="ij"), -1).reshape(-1, 2)
    nl = NeighbourList.build(x, support=2.5, skin=0.4, inner_reach=0.5)
    assert inner_pairs(nl) == brute_force_pairs(x, 1.65)
    assert not nl.stale(x, 2.5)
    assert nl.stale(x, 2.6)  # the support grew: both lists are short
    moved = x.copy()
    moved[7] += 0.3
    nl.update(moved, support=2.5)
    assert nl.builds == 2 and nl.inner_reach == 0.5
    assert inner_pairs(nl) == brute_force_pairs(moved, 1.65)


def _morton_reference(cell: np.ndarray) -> int:
    """A cell's Z-order code, bit by bit in Python: bit ``b`` of axis ``a`` at ``b dim + a``."""
    dim = cell.shape[0]
    return sum(((int(cell[a]) >> b) & 1) << (b * dim + a)
               for b in range(63 // dim) for a in range(dim))


def _stencil_order_reference(x: np.ndarray, radius: float) -> tuple[np.ndarray, list[list[int]]]:
    """The list the builder is specified to make, written plainly: particles sorted (stably)
    by the Morton code of their cell, each one's neighbours found cell by cell over the
    ``3**dim`` stencil with axis 0 fastest, the particles of a cell in sorted order."""
    n, dim = x.shape
    lo = x.min(axis=0)
    ncell = np.maximum(1, ((x.max(axis=0) - lo) / radius).astype(np.int64) + 1)
    cells = np.clip(((x - lo) / radius).astype(np.int64), 0, ncell - 1)
    key = np.ravel_multi_index(tuple(cells.T), tuple(ncell))
    order = np.argsort([_morton_reference(c) for c in cells], kind="stable")
    xs = x[order]
    cell_of = key[order]
    own = np.clip(((xs - lo) / radius).astype(np.int64), 0, ncell - 1)
    rows = []
    for p in range(n):
        row = []
        for s in range(3**dim):
            offset = [(s // 3**a) % 3 - 1 for a in range(dim)]
            c = own[p] + offset
            if np.any(c < 0) or np.any(c >= ncell):
                continue
            k = 0
            for a in range(dim):
                k = k * ncell[a] + c[a]
            for q in np.flatnonzero(cell_of == k):
                if q != p and np.sum((xs[p] - xs[q]) ** 2) < radius * radius:
                    row.append(int(q))
        rows.append(row)
    return order, rows


def _split_row(row: list[int], xs: np.ndarray, p: int, front_limit, dim: int,
               inner_limit: float = 0.0) -> list[int]:
    """A row as the builder is specified to split it in 2D and 3D: the entries ``q`` with
    ``|x_p - x_q|^2 < front_limit(q)`` first, in the row's order, then the rest in the reverse
    order (1D rows are not split); with an inner list, the entries with ``|x_p - x_q|^2 <
    inner_limit`` ahead of all, in the row's order (in 1D too)."""
    r2 = [float(np.sum((xs[p] - xs[q]) ** 2)) for q in row]
    inner = [q for q, d in zip(row, r2, strict=True) if d < inner_limit]
    rest = [(q, d) for q, d in zip(row, r2, strict=True) if not d < inner_limit]
    if dim < 2:
        return inner + [q for q, _ in rest]
    return (inner + [q for q, d in rest if d < front_limit(q)]
            + [q for q, d in rest if not d < front_limit(q)][::-1])


def _check_splits(nl: NeighbourList, dim: int) -> None:
    """2D and 3D: ``splits`` marks each row's front part; 1D lists have none."""
    if dim < 2:
        assert nl.splits is None
        np.testing.assert_array_equal(nl.filter_starts, nl.offsets[:-1])
        # one view while the offsets are the same array (a pass's arguments stay the same
        # objects, which the chunked passes' lookup finds at once), a new one for new offsets
        assert nl.filter_starts is nl.filter_starts
        before, offsets = nl.filter_starts, nl.offsets
        nl.offsets = offsets + 0
        assert nl.filter_starts is not before and nl.filter_starts.base is nl.offsets
        np.testing.assert_array_equal(nl.filter_starts, before)
        nl.offsets = offsets
        return
    assert nl.splits.shape == (nl.offsets.shape[0] - 1,)
    assert np.all(nl.offsets[:-1] <= nl.splits) and np.all(nl.splits <= nl.offsets[1:])
    assert nl.filter_starts is nl.splits


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_list_order_is_the_stencil_order(dim):
    """Each particle's neighbours in the order the pair sums take them (their order sets the
    sums' last bits): random points, and a lattice with points on the cell borders, near the
    origin and far from it (where the stencil's cells that the builder skips as out of reach
    are decided in round-off: none that holds a neighbour may be skipped).  With a skin, a 2D
    or 3D row holds the pairs within the support first, in the stencil's order, then the skin's in
    the reverse order, and ``splits`` says where the second part starts."""
    rng = np.random.default_rng(20 + dim)
    dx = 0.25
    side = {1: 30, 2: 9, 3: 5}[dim]
    axis = np.arange(side) * dx
    lattice = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    shuffled = lattice[rng.permutation(len(lattice))]
    jittered = shuffled + rng.uniform(-0.05, 0.05, shuffled.shape)
    for x, support, skin in ((rng.random((150, dim)), 0.21, 0.0), (shuffled, 0.5, 0.0),
                             (shuffled, 0.75, 0.0), (shuffled + 1e4 / 3.0, 0.5, 0.0),
                             (rng.random((150, dim)) - 1e3, 0.21, 0.0),
                             (jittered, 0.5, 0.1), (rng.random((150, dim)), 0.19, 0.02)):
        for reach in (1.0, 0.5):  # (0.5: with an inner list, each row's first entries)
            nl = NeighbourList.build(x, support, skin, inner_reach=reach)
            order, rows = _stencil_order_reference(x, nl.radius)
            np.testing.assert_array_equal(nl.order, order)
            _check_splits(nl, dim)
            xs = x[order]
            front = (nl.radius - skin) ** 2
            inner = nl.inner_radius ** 2
            for p, row in enumerate(rows):
                expected = _split_row(row, xs, p, lambda q, f=front: f, dim, inner)
                assert nl.indices[nl.offsets[p]:nl.offsets[p + 1]].tolist() == expected, p
                if reach < 1.0:
                    within = np.sum((xs[row] - xs[p]) ** 2, axis=1) < inner
                    assert nl.inner_ends[p] - nl.offsets[p] == within.sum(), p
                if dim > 1:
                    front_part = nl.indices[nl.offsets[p]:nl.splits[p]]
                    assert np.all(np.sum((xs[front_part] - xs[p]) ** 2, axis=1) < front), p
                    if skin == 0.0:  # without a skin every pair is within the support
                        assert nl.splits[p] == nl.offsets[p + 1]


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_a_radius_per_pair_keeps_each_pairs_own_support(dim):
    """Built with a smoothing length per particle, the list holds exactly the pairs closer than
    ``2 h_ij + skin`` (or than the inner list's radius), in the order the whole list has them,
    and its inner list is the global one's."""
    rng = np.random.default_rng(20 + dim)
    x = rng.random((500 if dim < 3 else 1200, dim)) * [1.0, 0.7, 0.5][:dim]
    # (in 3D more particles and a few with a larger h: each particle's reach, which the
    # builder's pruning of the stencil's cells takes from its own h and the largest, is then
    # well short of the radius, and pairs lie near that reach)
    h = rng.uniform(0.03, 0.05, x.shape[0])
    if dim == 3:
        h[rng.random(x.shape[0]) < 0.05] = 0.08
    support, skin, reach = 2.0 * h.max(), 0.01, 0.3
    nl = NeighbourList.build(x, support, skin, inner_reach=reach, h=h)
    whole = NeighbourList.build(x, support, skin, inner_reach=reach)
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    own = np.maximum(2.0 * 0.5 * (h[:, None] + h[None, :]) + skin, nl.inner_radius)
    i, j = np.nonzero((d < own) & (d < nl.radius))
    expected = {(int(a), int(b)) for a, b in zip(i, j, strict=True) if a != b}
    assert pairs_of(nl) == expected
    assert nl.n_pairs < whole.n_pairs  # the rows are shorter
    np.testing.assert_array_equal(nl.order, whole.order)
    _check_splits(nl, dim)
    # each row: the stencil-ordered pairs it keeps, in 2D and 3D those within their own support
    # ``2 h_ij`` (or the inner list's radius) first (the builder's arithmetic, written out)
    _, rows = _stencil_order_reference(x, nl.radius)
    xs, hs = x[nl.order], h[nl.order]
    inner2 = min(nl.inner_radius, nl.radius) ** 2

    def limits(p, q):
        reach = 0.5 * 2.0 * (hs[p] + hs[q]) + skin
        kept = min(nl.radius ** 2, max(reach * reach, inner2))
        return kept, min(kept, max((reach - skin) ** 2, inner2))

    for p in range(0, x.shape[0], 7):
        row = [q for q in rows[p] if np.sum((xs[p] - xs[q]) ** 2) < limits(p, q)[0]]
        expected = _split_row(row, xs, p, lambda q, p=p: limits(p, q)[1], dim, inner2)
        assert nl.indices[nl.offsets[p]:nl.offsets[p + 1]].tolist() == expected, p
    np.testing.assert_array_equal(inner_entries(nl), inner_entries(whole))
    with pytest.raises(ValueError, match="h has 3 rows"):
        NeighbourList.build(x, support, skin, h=h[:3])


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_the_cell_sort_is_a_stable_sort_by_the_cells_z_order(dim):
    """The builder's counting sort over the occupied cells gives the order of a stable sort of
    the particles by their cells' Morton codes, and each cell's range of sorted positions:
    checked on two clusters far apart (most cells empty), with particles sharing cells and
    some on the box's far faces (clamped into the last cell)."""
    from impactsph.neighbours import cell_sort

    rng = np.random.default_rng(dim)
    x = np.concatenate([rng.random((150, dim)) * 3.0, 40.0 + rng.random((150, dim)) * 2.0,
                        np.full((3, dim), 42.0)])
    x = x[rng.permutation(x.shape[0])]
    lo, radius = x.min(axis=0), 0.7
    ncell = np.maximum(1, ((x.max(axis=0) - lo) / radius).astype(np.int64) + 1)
    cells = np.clip(((x - lo) / radius).astype(np.int64), 0, ncell - 1)
    codes = np.array([_morton_reference(c) for c in cells])
    order, cell_start, cell_end = cell_sort(x, lo, radius, ncell)
    np.testing.assert_array_equal(order, np.argsort(codes, kind="stable"))
    keys = np.ravel_multi_index(tuple(cells.T), tuple(ncell))
    assert cell_start.shape == cell_end.shape == (int(np.prod(ncell)),)
    for k in range(cell_start.shape[0]):
        np.testing.assert_array_equal(np.sort(order[cell_start[k]:cell_end[k]]),
                                      np.flatnonzero(keys == k))


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_the_list_in_shares_is_the_list_in_one(dim, monkeypatch):
    """The builder's sweeps run in shares of the rows' chunks on numba's threads
    (:func:`impactsph.physics.chunked.run_chunked`): built in three shares (whatever this
    worker's thread count), every array of the list, its inner list, splits and order, is the
    one share's to the bit, with a radius per pair too (the stretch's lists)."""
    import impactsph.neighbours as neighbours

    rng = np.random.default_rng(40 + dim)
    x = rng.random((700, dim)) * [1.0, 0.6, 0.5][:dim]  # 11 chunks of 64 rows
    h = 0.05 * (1.0 + 0.3 * rng.random(700))
    lists = []
    for shares in (1, 3):
        monkeypatch.setattr(neighbours, "threads_for", lambda rows, chunk, threaded, k=shares: k)
        lists.append([NeighbourList.build(x, 0.13, 0.02, inner_reach=0.5),
                      NeighbourList.build(x, 0.13, 0.02, inner_reach=0.5, h=h)])
    for one, three in zip(*lists, strict=True):
        assert one.indices.size > 5 * len(x)  # rows of several neighbours
        for field in ("order", "offsets", "indices", "inner_ends", "splits"):
            a, b = getattr(one, field), getattr(three, field)
            assert (a is None) == (b is None) == (field == "splits" and dim == 1), field
            if a is not None:
                np.testing.assert_array_equal(a, b, err_msg=field)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_one_sweep_gives_the_list_of_two(dim, monkeypatch):
    """A list built in one sweep, each share of rows stored in a room sized from the list it
    replaces (``NeighbourList.build``'s ``like``) and the rooms then moved together, is the
    list of a count and a store to the bit: in one share and in three (whatever this
    worker's thread count), with an inner list, a skin (the rows' two parts) and a radius
    per pair; from a list of other rows (fewer: the ghosts come and go); and a room too
    small for a share makes the build sweep twice, to the same list.  (1D lists, of a few
    entries a row, are always swept twice.)"""
    import impactsph.neighbours as neighbours

    rng = np.random.default_rng(50 + dim)
    x = rng.random((700, dim)) * [1.0, 0.6, 0.5][:dim]  # 11 chunks of 64 rows
    h = 0.05 * (1.0 + 0.3 * rng.random(700))
    for shares in (1, 3):
        monkeypatch.setattr(neighbours, "threads_for", lambda rows, chunk, threaded, k=shares: k)
        for per_pair in (None, h):
            two = NeighbourList.build(x, 0.13, 0.02, inner_reach=0.5, h=per_pair)
            fewer = NeighbourList.build(x[:-60], 0.13, 0.02, inner_reach=0.5,
                                        h=None if per_pair is None else per_pair[:-60])
            short = two.offsets // 2
            assert two.sweeps == 2 and two.indices.size > 5 * len(x)
            # (from fewer rows the room is an estimate: one sweep or two)
            once = {1} if dim > 1 else {2}
            for like, sweeps in ((two.offsets, once), (fewer.offsets, once | {2}),
                                 (short, {2})):
                one = NeighbourList.build(x, 0.13, 0.02, inner_reach=0.5, h=per_pair,
                                          like=like)
                assert one.sweeps in sweeps
                for field in ("order", "offsets", "indices", "inner_ends", "splits"):
                    a, b = getattr(two, field), getattr(one, field)
                    assert (a is None) == (b is None) == (field == "splits" and dim == 1)
                    if a is not None:
                        assert a.dtype == b.dtype, field
                        np.testing.assert_array_equal(a, b, err_msg=field)
                if one.sweeps == 1:  # its room beyond the list given back, not a view of it
                    assert one.indices.flags.owndata and one.indices.base is None


def test_a_runs_rebuilds_take_one_sweep():
    """The solver hands each build the list it replaces: a run's rebuilds sweep once (a
    plane-strain Taylor bar on its wall, whose ghosts come and go)."""
    from impactsph.loading import load_case
    from impactsph.simulation import Simulation

    sim = Simulation(load_case("taylor", ["bodies.0.geometry.count=[6, 12]",
                                          "time.neighbour_skin=0.02"]))
    assert sim.solver.neighbours.sweeps == 2  # (the first build has no list before it)
    sweeps = []
    while sim.solver.neighbours.builds < 6:
        builds = sim.solver.neighbours.builds
        sim.run(t_end=sim.time + 2e-7)
        if sim.solver.neighbours.builds > builds:
            sweeps.append(sim.solver.neighbours.sweeps)
    assert sweeps and set(sweeps) == {1}


@pytest.mark.parametrize(("h_over_dx", "pairs", "entries"),
                         [(1.2, {2: 20, 3: 56}, {2: 20, 3: 80}),
                          (1.3, {2: 20, 3: 80}, {2: 24, 3: 92}),
                          (1.5, {2: 24, 3: 92}, {2: 36, 3: 146})])
def test_a_lattice_particles_pairs_and_list_entries_are_docs_performance_table(
        h_over_dx, pairs, entries):
    """docs/performance.md's table of pairs a particle: inside a square or cubic lattice, the
    neighbours within the support ``2 h`` (what the pair passes evaluate) and the list's
    entries with the default skin (0.1 of the support), at h = 1.2, 1.3 and 1.5 dx."""
    for dim in (2, 3):
        side = 11
        x = np.stack(np.meshgrid(*[np.arange(float(side))] * dim, indexing="ij"),
                     -1).reshape(-1, dim)
        support = 2.0 * h_over_dx
        nl = NeighbourList.build(x, support, 0.1 * support)
        centre = int(np.flatnonzero((x == side // 2).all(axis=1))[0])
        p = int(np.flatnonzero(nl.order == centre)[0])
        row = nl.order[nl.indices[nl.offsets[p]:nl.offsets[p + 1]]]
        distance = np.linalg.norm(x[row] - x[centre], axis=1)
        assert row.size == entries[dim], (dim, row.size)
        assert int((distance < support).sum()) == pairs[dim], dim
