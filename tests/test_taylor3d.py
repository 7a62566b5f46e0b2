"""The Taylor bar as a 3D cylinder (examples/taylor3d.toml), coarsened to 1404 particles
(R = 4 dx) and run to 15 us (217 steps): it must stay axisymmetric, shorten, spread its foot
and stay off the wall, and the run must give the 3D measures and figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactsph.config import AUTO_MAX_STRETCH
from impactsph.loading import load_case
from impactsph.runner import run_case

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "taylor3d.toml"
DX = 0.95e-3
END = 15e-6


def coarse_run(out: Path):
    case = load_case(EXAMPLE, [f"bodies.0.geometry.spacing={DX}", f"time.end={END}",
                               f"output.snapshot_times=[{END}]"])
    held = []
    summary = run_case(case, out, callback=lambda s: held.append(s) if not held else None)
    return held[0], summary


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return coarse_run(tmp_path_factory.mktemp("taylor3d"))


def test_example_is_the_plane_strain_bar_as_a_cylinder():
    c3, c2 = load_case(EXAMPLE), load_case("taylor")
    g3, g2 = c3.bodies[0].geometry, c2.bodies[0].geometry
    assert 2 * g3.radius == pytest.approx(g2.size[0]) and g3.length == pytest.approx(g2.size[1])
    assert c3.materials == c2.materials and c3.kernel.h_over_dx == c2.kernel.h_over_dx
    # the paper's bar keeps its fixed h; the cylinder, a case of its own, gets the kernel that
    # follows the stretch (kernel.max_stretch = "auto": docs/stabilisation.md, "Defaults")
    assert c2.kernel.max_stretch == 1.0 and c3.kernel.max_stretch == AUTO_MAX_STRETCH
    assert c3.time == c2.time
    # the correction in its pairwise form: the paper's eq 34 blows up at twice the
    # resolution in 3D (the example's header; docs/dissipation.md)
    assert c2.viscosity.scheme == "ac" and c3.viscosity.scheme == "ac_pairwise"
    assert c3.bodies[0].velocity == [0.0, 0.0, c2.bodies[0].velocity[1]]
    assert [w.slip for w in c3.boundaries] == [w.slip for w in c2.boundaries] == ["free"]
    # the spacing lies between the plane-strain lattice's two spacings
    assert min(g2.spacings()) <= g3.spacing <= max(g2.spacings())


def _partner(x0: np.ndarray, mirror) -> np.ndarray:
    """Index of each particle's image under ``mirror`` (a map of the initial lattice onto
    itself)."""
    index = {tuple(k): i for i, k in enumerate(np.rint(x0 / (0.5 * DX)).astype(int))}
    return np.array([index[tuple(k)] for k in np.rint(mirror(x0) / (0.5 * DX)).astype(int)])


def test_coarse_cylinder_stays_axisymmetric(run):
    sim, _ = run
    x0, x = sim.state.initial_position, sim.state.position
    # the lattice is symmetric under x <-> y and x -> -x; so must the deformed bar be, to
    # round-off (measured 8e-15 dx): the lateral directions are treated alike
    swap = _partner(x0, lambda p: p[:, [1, 0, 2]])
    flip = _partner(x0, lambda p: p * [-1.0, 1.0, 1.0])
    assert np.abs(x[swap][:, [1, 0, 2]] - x).max() < 1e-9 * DX
    assert np.abs(x[flip] * [-1.0, 1.0, 1.0] - x).max() < 1e-9 * DX
    # the footprint reaches as far along x as along y, and its centroid stays on the axis
    foot = x[:, 2] < DX
    assert np.abs(x[foot, 0]).max() == pytest.approx(np.abs(x[foot, 1]).max(), rel=1e-9)
    m = sim.state.mass
    assert np.abs(m @ x[:, :2]).max() / m.sum() < 1e-12 * DX
    assert np.abs(m @ sim.state.velocity[:, :2]).max() / (m.sum() * 200.0) < 1e-12


def test_coarse_cylinder_shortens_and_spreads_on_the_wall(run):
    sim, s = run
    case = load_case(EXAMPLE, [f"bodies.0.geometry.spacing={DX}"])
    g = case.bodies[0].geometry
    assert sim.state.mass.sum() == pytest.approx(
        case.materials["iron"].density * np.pi * g.radius**2 * g.length, rel=0.1)
    assert sim.state.position[:, 2].min() > 0  # nothing crossed the wall
    assert s["wall_constraint_events"] == 0  # the ghosts held it off, not the constraint
    # measured at 15 us: L/L0 0.9068, footprint 1.383 R0 (the smallest sector 1.315), energy
    # error 5.5e-4 (the paper's AC: 0.9068, 1.388, 1.319, 3.0e-4)
    assert 0.85 < s["final_length_ratio"] < 0.95
    assert 1.25 < s["footprint_radius_ratio"] < 1.6
    assert s["footprint_radius_ratio_min_sector"] > 0.9 * s["footprint_radius_ratio"]
    assert s["footprint_radius"] == pytest.approx(s["footprint_radius_ratio"]
                                                  * s["initial_radius"])
    assert "footprint_half_width_ratio" not in s  # that is the plane-strain measure
    assert s["plastic_work"] > 0
    assert s["total_energy_relative_error"] < 2e-3
    assert s["kinetic_energy_ratio_final"] < 0.6  # the bar is being stopped


def test_coarse_cylinder_run_directory(run):
    sim, s = run
    names = {Path(p).name for p in s["figures"]}
    assert names == {"kinetic_energy.png", "energies.png", "deformed_shape.png"}
    assert all(Path(p).stat().st_size > 10_000 for p in s["figures"])


def test_the_wall_layer_holds_the_spreading_foot_off_the_wall(tmp_path):
    """Issue 11: the impact face of the cylinder thins as it spreads (as 1/lambda^2) and,
    with the paper's wall (the ghosts' pressure contact, no penalty layer), its particles
    reach the wall plane, where only the constraint stops them (measured at 40 us: 1840
    constraint events, energy error 6.6e-4).  With the defaults (the normal-stress contact
    and ``contact.wall_layer = 0.25``) none reaches it and the energy error halves
    (3.0e-4).  Both with the paper's AC, which these numbers were measured with (the
    example's pairwise correction is not what this test is about)."""
    got = {}
    for name, contact in (("paper", ['contact.traction="pressure"', "contact.wall_layer=0"]),
                          ("defaults", [])):
        case = load_case(EXAMPLE, [f"bodies.0.geometry.spacing={DX}", "time.end=40e-6",
                                   "output.snapshot_times=[]", "output.figures=false",
                                   'viscosity.scheme="ac"', *contact])
        last: dict = {}
        s = run_case(case, tmp_path / name, callback=lambda sim, last=last: last.update(sim=sim))
        got[name] = (s, last["sim"].state.position[:, 2].min())
    bare, held = got["paper"][0], got["defaults"][0]
    assert bare["wall_constraint_events"] > 100  # the failure the layer is for
    assert held["wall_constraint_events"] == 0
    assert got["defaults"][1] > 0.05 * DX  # held off the plane, not put back onto it
    assert held["total_energy_relative_error"] < 1e-3
    assert held["total_energy_relative_error"] < bare["total_energy_relative_error"]
    # the same bar: the wall options change the length and foot by a few per cent
    assert held["final_length_ratio"] == pytest.approx(bare["final_length_ratio"], rel=0.03)
    assert held["footprint_radius_ratio"] == pytest.approx(bare["footprint_radius_ratio"],
                                                           rel=0.05)


def test_axisymmetric_bar_has_the_cylinders_length(run, tmp_path):
    """The same bar in 2D axisymmetry (the built-in case taylor_axisymmetric) at this spacing
    (4 x 27 particles: R = 4 dx) to the same time: L_f / L_0 within 2% of the cylinder's
    (measured 0.90666 against 0.90682; the full runs at two resolutions are in
    docs/validation.md)."""
    _, summary = run
    case = load_case("taylor_axisymmetric", ["bodies.0.geometry.count=[4, 27]", f"time.end={END}",
                           f"output.snapshot_times=[{END}]"])
    got = run_case(case, tmp_path / "axi", figures=False)
    assert got["final_length_ratio"] == pytest.approx(summary["final_length_ratio"], rel=0.02)
    assert got["final_length_ratio"] < 0.95  # the bar has shortened
    assert abs(got["total_energy_relative_error"]) < 2e-3
