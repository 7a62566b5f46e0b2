"""Prescribed motion: a rod held at one end and pulled at the other at a prescribed velocity
carries the stress of elastic wave theory, its reaction recorded, the supports' work booked;
several clamped regions; bad input refused with exit code 2 and one line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph import Simulation, load_case
from impactsph.cli import app

E, NU, RHO = 200e9, 0.3, 7850.0
L, H, DX = 0.04, 0.004, 0.0005
PULL = 1.0  # m/s

CASE = f"""
name = "pulled_rod"
dimension = 2

[materials.steel]
model = "elastic"
density = {RHO}
youngs_modulus = {E}
poisson_ratio = {NU}

[[bodies]]
name = "rod"
material = "steel"
velocity = [0.0, 0.0]
clamped = [{{origin = [-0.001, -0.001], size = [0.0015, 0.006]}}]
[bodies.geometry]
origin = [0.0, 0.0]
size = [{L}, {H}]
spacing = {DX}
[[bodies.driven]]
name = "grip"
origin = [{L - 0.0015}, -0.001]
size = [0.0025, 0.006]
velocity = [@PULL@, 0.0]

[kernel]
h_over_dx = 1.3

[viscosity]
alpha1 = 0.5
alpha2 = 0.5

[time]
end = @END@

[output]
figures = false
"""


def run(tmp_path, pull: str = str(PULL), end: float = 10e-6, overrides=()) -> Simulation:
    path = tmp_path / "rod.toml"
    path.write_text(CASE.replace("@PULL@", pull).replace("@END@", repr(end)))
    sim = Simulation(load_case(path, list(overrides)))
    sim.run()
    return sim


@pytest.mark.parametrize("integrator", [
    [], ['time.integrator="ssp_rk3"', "time.courant=0.45"]], ids=["midpoint", "ssp_rk3"])
def test_pulled_rod_carries_the_wave_stress(tmp_path, integrator):
    """Pulled at v, the rod carries sigma = rho c v behind the front (c the long-wave speed of
    a plane-strain strip, sqrt(E / (rho (1 - nu^2)))): the grip's reaction is sigma H until the
    front, reflected at the clamp, comes back after 2 L / c.  With either integrator (the
    three-stage one books the step's mean reaction and the clamps' impulse)."""
    c = math.sqrt(E / (RHO * (1 - NU**2)))
    sim = run(tmp_path, overrides=integrator)
    h = sim.record.history
    t = np.array([r["time"] for r in h])
    force = np.array([r["reaction_force_grip_x"] for r in h])
    expected = RHO * c * PULL * H
    window = (t > 0.25 * L / c) & (t < 0.9 * L / c)  # after the start, before the reflection
    assert window.sum() > 50
    mean = float(force[window].mean())
    assert mean == pytest.approx(expected, rel=0.06), (mean, expected)
    # the grip moved at the prescribed velocity
    grip = sim.integrator.drivers.regions[0].rows
    np.testing.assert_allclose(sim.state.velocity[grip], [[PULL, 0.0]] * grip.size)
    moved = sim.state.position[grip, 0] - sim.state.initial_position[grip, 0]
    np.testing.assert_allclose(moved, PULL * sim.state.time, rtol=1e-9)  # sums of dt
    # KE + IE - the grip's work is kept
    assert abs(sim.summary()["total_energy_relative_error"]) < 1e-3
    assert h[-1]["external_work"] > 0


def test_a_velocity_ramp_from_an_expression(tmp_path):
    """v_p = where(t < 2 us, PULL t / 2 us, PULL): the grip follows it."""
    sim = run(tmp_path, pull=f'"where(t < 2e-6, {PULL} * t / 2e-6, {PULL})"', end=1e-6)
    grip = sim.integrator.drivers.regions[0].rows
    assert sim.state.velocity[grip, 0] == pytest.approx(PULL * sim.state.time / 2e-6)
    assert abs(sim.summary()["total_energy_relative_error"]) < 1e-3


runner = CliRunner()


@pytest.mark.parametrize(("change", "field"), [
    (("velocity = [@PULL@, 0.0]", 'velocity = ["2 * q", 0.0]'), "bodies.0.driven.0.velocity.0"),
    (("velocity = [@PULL@, 0.0]", "velocity = [1.0]"), "bodies.0.driven.0.velocity has 1"),
    ((f"origin = [{L - 0.0015}, -0.001]", "origin = [1.0, 1.0]"), "bodies.0.driven.0 holds no"),
])
def test_bad_driven_regions_refused(tmp_path, change, field):
    path = tmp_path / "rod.toml"
    path.write_text(CASE.replace(*change).replace("@PULL@", str(PULL)).replace("@END@", "1e-6"))
    res = runner.invoke(app, ["run", str(path), "--quiet", "--out", str(tmp_path / "out")])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and field in lines[0], lines


def test_restart_continues_the_supports_work(tmp_path):
    """A driven run restarted from its checkpoint ends where the straight run ends, the
    supports' work and impulse included."""
    from impactsph.checkpoint import load_checkpoint
    from impactsph.runner import run_case

    path = tmp_path / "rod.toml"
    path.write_text(CASE.replace("@PULL@", str(PULL)).replace("@END@", "3e-6"))
    case = load_case(path, [f"output.checkpoint_interval={3e-6 / 3.5}"])
    run_case(case, tmp_path / "whole")
    reference = Simulation(case)
    reference.run()
    restarted = load_checkpoint(tmp_path / "whole" / "checkpoint.h5", case)
    assert 0 < restarted.state.time < 3e-6
    restarted.run()
    np.testing.assert_array_equal(restarted.state.velocity, reference.state.velocity)
    drivers, ref = restarted.integrator.drivers, reference.integrator.drivers
    assert drivers.work == pytest.approx(ref.work, rel=1e-12)
    np.testing.assert_allclose(drivers.impulse, ref.impulse, rtol=1e-12)
