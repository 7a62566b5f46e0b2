"""Symmetry planes: a half (or quarter) model with mirror ghosts equals the whole model.

The paper's plane-strain Taylor bar (AC viscosity, the free-slip wall below) with an even
number of particles across, so that none sits on the axis: the half x > 0 with a symmetry
plane at x = 0 must follow the whole bar's x > 0 half to round-off, with the schemes that read
the ghosts' per-particle results too (the acceleration correction reads their viscous
acceleration, the hourglass control their velocity gradient, the kernel gradient correction
their positions).  And the 3D Taylor cylinder: a quarter with two planes against the whole.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactsph import Simulation
from impactsph.config import CaseError
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
    rows, own = matched(whole, half)
    scale = float(np.abs(whole.state.velocity).max())
    for name in ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
                 "plastic_work"):
        a = getattr(whole.state, name)[rows]
        b = getattr(half.state, name)[own]
        tol = {"position": 1e-12 * 0.0254, "velocity": 1e-9 * scale}.get(
            name, 1e-9 * float(np.abs(a).max() or 1.0))
        np.testing.assert_allclose(b, a, rtol=0, atol=tol, err_msg=name)
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


def test_quarter_cylinder_equals_the_whole(tmp_path):
    """The 3D Taylor cylinder (10 particles across, 1 us): the quarter x > 0, y > 0 (its
    particles read from a file) with two symmetry planes against the whole cylinder."""
    data = read_case_dict(EXAMPLES / "taylor3d.toml")
    geometry = data["bodies"][0]["geometry"]
    geometry["spacing"] = 0.0254 / 33
    overrides = ["time.end=1e-6", "output.snapshot_times=[]", "output.figures=false"]
    whole = Simulation(validate_case(apply_overrides(data, overrides)))
    x = whole.state.position.copy()
    quarter = (x[:, 0] > 0) & (x[:, 1] > 0)
    spacing = geometry["spacing"]
    np.savez(tmp_path / "quarter.npz", position=x[quarter],
             volume=np.full(int(quarter.sum()), spacing**3))
    part = dict(data)
    part["bodies"] = [dict(data["bodies"][0], geometry={
        "type": "file", "path": str(tmp_path / "quarter.npz"), "spacing": spacing})]
    part["boundaries"] = [*data["boundaries"],
                          {"type": "symmetry", "point": [0.0, 0.0, 0.0], "normal": [1.0, 0, 0]},
                          {"type": "symmetry", "point": [0.0, 0.0, 0.0], "normal": [0, 1.0, 0]}]
    part["analysis"] = "none"
    whole.run()
    q = Simulation(validate_case(apply_overrides(part, overrides)))
    q.run()
    assert q.state.step == whole.state.step
    rows, own = matched(whole, q)
    scale = float(np.abs(whole.state.velocity).max())
    np.testing.assert_allclose(q.state.velocity[own], whole.state.velocity[rows], rtol=0,
                               atol=1e-9 * scale)
    np.testing.assert_allclose(q.state.deviatoric_stress[own],
                               whole.state.deviatoric_stress[rows], rtol=0,
                               atol=1e-9 * float(np.abs(whole.state.deviatoric_stress).max()))
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
    rows, own = matched(whole, part)
    scale = float(np.abs(whole.state.velocity).max())
    np.testing.assert_allclose(part.state.velocity[own], whole.state.velocity[rows], rtol=0,
                               atol=1e-9 * scale)
    np.testing.assert_allclose(part.state.specific_energy[own],
                               whole.state.specific_energy[rows], rtol=0,
                               atol=1e-9 * float(np.abs(whole.state.specific_energy).max()))
    assert whole.state.specific_energy.max() > 0  # the flow heats: the viscosity acted
