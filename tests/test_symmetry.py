"""Symmetry planes: a half (or quarter) model with mirror ghosts equals the whole model.

The paper's plane-strain Taylor bar (AC viscosity, the free-slip wall below) with an even
number of particles across, so that none sits on the axis: the half x > 0 with a symmetry
plane at x = 0 must follow the whole bar's x > 0 half to round-off, with the schemes that read
the ghosts' per-particle results too (the acceleration correction reads their viscous
acceleration, the hourglass control their velocity gradient, the kernel gradient correction
their positions).  And the 3D Taylor cylinder: a quarter with two planes against the whole.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from impactsph import Simulation
from impactsph.config import CaseError
from impactsph.geometry import quarter_cylinder_case
from impactsph.loading import apply_overrides, read_case_dict, validate_case

STEPS_END = 2.0e-6
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def taylor(half: bool, extra: list[str]) -> Simulation:
    data = read_case_dict("taylor")
    geometry = data["bodies"][0]["geometry"]
    if half:
        geometry.update(origin=[0.0, 0.0], size=[0.0038, 0.0254], count=[10, 67])
        data["boundaries"].append({"type": "symmetry", "point": [0.0, 0.0],
                                   "normal": [1.0, 0.0]})
    else:
        geometry.update(origin=[-0.0038, 0.0], size=[0.0076, 0.0254], count=[20, 67])
    data["output"] = {"figures": False}
    case = validate_case(apply_overrides(data, [f"time.end={STEPS_END}", *extra]))
    sim = Simulation(case)
    sim.run()
    return sim


def matched(whole: Simulation, part: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the whole model matching each particle of the part, by initial position."""
    x0w, x0p = whole.state.initial_position, part.state.initial_position
    keys = {tuple(np.round(x / 1e-9).astype(np.int64)): i for i, x in enumerate(x0w)}
    rows = np.array([keys[tuple(np.round(x / 1e-9).astype(np.int64))] for x in x0p])
    return rows, np.arange(part.state.n)


def assert_same_state(whole: Simulation, part: Simulation, names: tuple[str, ...]) -> None:
    """The part's particles have the whole model's fields to round-off: positions to 1e-12 of
    the bar's length, the rest to 1e-9 of the field's largest value."""
    rows, own = matched(whole, part)
    for name in names:
        a = getattr(whole.state, name)[rows]
        b = getattr(part.state, name)[own]
        tol = 1e-12 * 0.0254 if name == "position" else 1e-9 * float(np.abs(a).max() or 1.0)
        np.testing.assert_allclose(b, a, rtol=0, atol=tol, err_msg=name)


@pytest.mark.parametrize("extra", [
    [],  # the paper's AC scheme (the correction reads the ghosts' viscous acceleration)
    ['stabilisation.gradient_correction="velocity_gradient_and_forces"',
     "stabilisation.hourglass=2.0", 'viscosity.scheme="av"'],
    # the reconstructing viscosity (the pair pass reads the ghosts' velocity gradients: the
    # mirror R L R of their sources')
    ['viscosity.scheme="reconstruction"'],
], ids=["ac", "corrected-hourglass", "reconstruction"])
def test_half_taylor_bar_equals_the_whole(extra):
    whole, half = taylor(False, extra), taylor(True, extra)
    assert whole.state.step == half.state.step
    assert_same_state(whole, half, ("position", "velocity", "density", "specific_energy",
                                    "deviatoric_stress", "plastic_work"))
    assert whole.state.plastic_work.max() > 0  # the bar yields: a real test
    # energy: the half holds half of the whole's
    ws, hs = whole.summary(), half.summary()
    assert hs["kinetic_energy_final"] == pytest.approx(ws["kinetic_energy_final"] / 2,
                                                       rel=1e-9)
    # the momentum normal to the plane goes to the mirrored half; along it, the half's
    # balance is the whole's
    assert hs["momentum_drift"] == pytest.approx(ws["momentum_drift"], rel=1e-6)


def test_symmetry_plane_is_refused_on_the_gpu_and_checked():
    data = read_case_dict("taylor")
    data["boundaries"].append({"type": "symmetry", "point": [0.0], "normal": [1.0, 0.0]})
    with pytest.raises(CaseError, match="boundaries.1"):
        validate_case(data)


@pytest.mark.parametrize("arrangement", ["lattice", "rings"])
def test_quarter_cylinder_equals_the_whole(tmp_path, arrangement):
    """The 3D Taylor cylinder (10 particles across, 1 us): the quarter x > 0, y > 0 (its
    particles read from a file) with two symmetry planes against the whole cylinder, of the
    square lattice's layers or of concentric rings."""
    data = read_case_dict(EXAMPLES / "taylor3d.toml")
    geometry = data["bodies"][0]["geometry"]
    geometry["spacing"] = 0.0254 / 33
    geometry["arrangement"] = arrangement
    overrides = ["time.end=1e-6", "output.snapshot_times=[]", "output.figures=false"]
    whole = Simulation(validate_case(apply_overrides(data, overrides)))
    part = quarter_cylinder_case(copy.deepcopy(data), tmp_path)  # what the lab runs at x2
    part["analysis"] = "none"
    whole.run()
    q = Simulation(validate_case(apply_overrides(part, overrides)))
    q.run()
    assert q.state.step == whole.state.step
    assert q.state.n * 4 == whole.state.n
    assert_same_state(whole, q, ("velocity", "deviatoric_stress"))
    assert whole.state.plastic_work.max() > 0


def block(quarter: bool, extra: list[str]) -> Simulation:
    """A free 2D block (the Taylor bar's steel), the whole [-a, a]^2 or its quarter [0, a]^2
    with symmetry planes x = 0 and y = 0, in a converging flow symmetric about both axes and
    not linear (so that every viscosity acts): ``v = -k x (1 + |x|^2 / a^2)``."""
    a, n = 0.004, 10
    data = read_case_dict("taylor")
    data["bodies"][0]["geometry"] = (
        {"origin": [0.0, 0.0], "size": [a, a], "count": [n, n]} if quarter
        else {"origin": [-a, -a], "size": [2 * a, 2 * a], "count": [2 * n, 2 * n]})
    data["boundaries"] = ([{"type": "symmetry", "point": [0.0, 0.0], "normal": [1.0, 0.0]},
                           {"type": "symmetry", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]
                          if quarter else [])
    data["analysis"] = "none"
    data["output"] = {"figures": False}
    sim = Simulation(validate_case(apply_overrides(data, [f"time.end={STEPS_END}", *extra])))
    x = sim.state.position
    sim.state.velocity[:] = -5e4 * x * (1.0 + (x * x).sum(1, keepdims=True) / a**2)
    sim.run()
    return sim


@pytest.mark.parametrize("extra", [
    [],  # AC: the correction reads the corner images' viscous acceleration
    ['stabilisation.gradient_correction="velocity_gradient_and_forces"',
     "stabilisation.hourglass=2.0", 'viscosity.scheme="av"'],  # C and L of the corner images
    ['viscosity.scheme="reconstruction"'],  # the corner images' velocity gradients
], ids=["ac", "corrected-hourglass", "reconstruction"])
def test_quarter_block_with_a_corner_equals_the_whole(extra):
    """Two symmetry planes meet at a corner, where the ghosts include images of images: the
    per-particle results the later passes read (AC's viscous acceleration, the correction
    matrices, the velocity gradients) are the composed mirrors of their sources', so the
    quarter equals the whole to round-off (they were once the images' own, cut at the
    ghosts' reach, and the quarter differed near the corner)."""
    whole, part = block(False, extra), block(True, extra)
    assert whole.state.step == part.state.step
    assert_same_state(whole, part, ("velocity", "specific_energy"))
    assert whole.state.specific_energy.max() > 0  # the flow heats: the viscosity acted
