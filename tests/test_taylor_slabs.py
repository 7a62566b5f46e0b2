"""validation/taylor_slabs.py: the volume of a Taylor bar in slabs above the wall, from a
finite-element outline (clipped polygons, volumes of revolution) and from particles (a
cylinder of rings, whole or a quarter; an axisymmetric half-section), against exact ones."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from impactsph.geometry import block_particles, cylinder_particles

sys.path.insert(0, str(Path(__file__).parent.parent / "validation"))
import taylor_slabs as slabs  # noqa: E402

EDGES = np.array([0.0, 1.0, 2.5, 4.0]) * 1e-3


def frustum(r_low: float, r_high: float, z_low: float, z_high: float) -> np.ndarray:
    """The half-section outline of a cone frustum, counter-clockwise from the axis."""
    return np.array([[0.0, z_low], [r_low, z_low], [r_high, z_high], [0.0, z_high]])


@pytest.mark.parametrize("reverse", [False, True])
def test_outline_slabs_are_exact_on_a_frustum(reverse):
    """A frustum of radii 5 and 3 mm over 4 mm: each slab is a frustum too, ``pi dz (a^2 + a
    b + b^2) / 3`` in axisymmetry and ``dz (a + b)`` (twice the half's trapezium) in plane
    strain, with the outline in either orientation."""
    outline = frustum(5e-3, 3e-3, 0.0, 4e-3)
    if reverse:
        outline = outline[::-1]

    def radius(z):
        return 5e-3 - 0.5 * z

    exact_axi = [math.pi * (b - a) * (radius(a) ** 2 + radius(a) * radius(b) + radius(b) ** 2)
                 / 3 for a, b in zip(EDGES[:-1], EDGES[1:], strict=True)]
    exact_plane = [(b - a) * (radius(a) + radius(b))
                   for a, b in zip(EDGES[:-1], EDGES[1:], strict=True)]
    np.testing.assert_allclose(slabs.outline_slab_volumes(outline, EDGES, True), exact_axi,
                               rtol=1e-12)
    np.testing.assert_allclose(slabs.outline_slab_volumes(outline, EDGES, False), exact_plane,
                               rtol=1e-12)


def test_an_outline_that_crosses_a_slab_twice():
    """A foot whose lower surface curls up (the outline crosses the level z = 1 mm on the
    lower surface and on the side): the slab holds the part between them only."""
    # a rectangle r < 4 mm, z < 3 mm, less a notch under the rim: r > 2 mm, z < 1.5 mm
    outline = np.array([[0.0, 0.0], [2e-3, 0.0], [2e-3, 1.5e-3], [4e-3, 1.5e-3],
                        [4e-3, 3e-3], [0.0, 3e-3]])
    got = slabs.outline_slab_volumes(outline, np.array([0.0, 1e-3, 3e-3]), True)
    np.testing.assert_allclose(got, [math.pi * 4e-6 * 1e-3,
                                     math.pi * 4e-6 * 0.5e-3 + math.pi * 16e-6 * 1.5e-3],
                               rtol=1e-12)


def test_a_level_that_cuts_the_outline_into_two_pieces():
    """A lip that hangs down beside the bar with a gap between them (an overhang): the level
    z = 1 mm cuts the section into two pieces, the bar and the lip, and each slab holds both
    (plane strain: twice the half's area)."""
    mm = 1e-3
    # the bar r < 3 mm up to 3 mm; a gap 3 < r < 4 mm below 2.5 mm; a lip 4 < r < 5 mm
    # hanging from 3 mm down to 0.5 mm
    outline = np.array([[0, 0], [3, 0], [3, 2.5], [4, 2.5], [4, 0.5], [5, 0.5], [5, 3],
                        [0, 3]], dtype=float) * mm
    got = slabs.outline_slab_volumes(outline, np.array([0.0, 1.0, 3.0]) * mm, False)
    below = 3 * 1 + 1 * 0.5  # the bar's and the lip's pieces under 1 mm (mm^2)
    above = 3 * 2 + 1 * 0.5 + 1 * 2  # the bar, the bridge over the gap, the lip
    np.testing.assert_allclose(got, [2 * below * mm**2, 2 * above * mm**2], rtol=1e-12)


def write_run(folder: Path, case: dict, x: np.ndarray, mass: np.ndarray,
              density: np.ndarray) -> Path:
    folder.mkdir(parents=True)
    (folder / "case.json").write_text(json.dumps({"case": case}))
    np.savez(folder / "snapshots.npz", times=np.array([0.0, 5e-5]), s1_position=x,
             s1_mass=mass, s1_density=density, s0_position=x, s0_mass=mass,
             s0_density=density)
    return folder


def test_particles_of_a_cylinder_whole_and_quarter(tmp_path):
    """A cylinder of rings (radius 3.8 mm, 4 mm long, layers of 0.25 mm): each slab whose
    edges fall between layers holds exactly ``pi R^2 dz``, and the quarter with two
    symmetry planes counts as the whole."""
    p = cylinder_particles([0.0, 0.0, 0.0], 3.8e-3, 4e-3, "z", 0.25e-3, "rings")
    rho = np.full(p.n, 7850.0)
    exact = math.pi * 3.8e-3**2 * np.diff(EDGES)
    whole = write_run(tmp_path / "whole", {"dimension": 3, "boundaries": []}, p.position,
                      p.volume * rho, rho)
    np.testing.assert_allclose(slabs.run_slab_volumes(whole, EDGES)[0], exact, rtol=1e-12)
    q = (p.position[:, 0] > 0) & (p.position[:, 1] > 0)
    planes = [{"type": "symmetry"}, {"type": "symmetry"}, {"type": "wall"}]
    quarter = write_run(tmp_path / "quarter", {"dimension": 3, "boundaries": planes},
                        p.position[q], p.volume[q] * rho[q], rho[q])
    volumes, info = slabs.run_slab_volumes(quarter, EDGES)
    np.testing.assert_allclose(volumes, exact, rtol=1e-12)
    assert info["symmetry_planes"] == 2


def test_particles_of_an_axisymmetric_half_section(tmp_path):
    """The axisymmetric bar's particles carry their mass per radian and the density ``rho
    r`` (per radian and per unit area of the r-z plane): ``2 pi r m / density`` is each
    particle's ring of volume, and the slabs add up to ``pi R^2 dz``."""
    p = block_particles([0.0, 0.0], [3.8e-3, 4e-3], [0.19e-3, 0.25e-3])
    r = p.position[:, 0]
    mass = 7850.0 * r * p.volume  # per radian
    density = 7850.0 * r
    case = {"dimension": 2, "two_dimensional": "axisymmetric",
            "boundaries": [{"type": "symmetry"}]}
    run = write_run(tmp_path / "axi", case, p.position, mass, density)
    volumes, info = slabs.run_slab_volumes(run, EDGES)
    assert info["axisymmetric"]
    # the ring of each particle's cell: 2 pi r dr dz, exact for the cell centred at r
    np.testing.assert_allclose(volumes, math.pi * 3.8e-3**2 * np.diff(EDGES), rtol=1e-12)


def test_particles_above_the_top_edge_are_not_counted(tmp_path):
    """The outline is clipped at the top edge: the particles must be too (``--edges 0 1 2``
    put the rest of the bar into its top slab, an audit, 2026-12-08)."""
    p = cylinder_particles([0.0, 0.0, 0.0], 3.8e-3, 4e-3, "z", 0.25e-3, "rings")
    rho = np.full(p.n, 7850.0)
    run = write_run(tmp_path / "whole", {"dimension": 3, "boundaries": []}, p.position,
                    p.volume * rho, rho)
    edges = np.array([0.0, 1.0, 2.0]) * 1e-3
    np.testing.assert_allclose(slabs.run_slab_volumes(run, edges)[0],
                               math.pi * 3.8e-3**2 * np.diff(edges), rtol=1e-12)
