"""Initial conditions: a velocity field per body from an expression of position and from a
particle file's columns, an initial temperature from a file; bad expressions refused with
exit code 2 and one line naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph import Simulation, load_case
from impactsph.cli import app
from impactsph.models.columns import TEMPERATURE
from impactsph.problem import build_problem

CASE = """
name = "spinning_disk"
dimension = 2

[materials.steel]
model = "elastic"
density = 7850.0
youngs_modulus = 200e9
poisson_ratio = 0.3

[[bodies]]
name = "disk"
material = "steel"
velocity = {velocity}
[bodies.geometry]
{geometry}

[kernel]
h_over_dx = 1.3

[time]
end = 2e-6

[output]
figures = false
"""

DISK = 'type = "disk"\ncentre = [0.0, 0.0]\nradius = 0.005\nspacing = 0.0005'
OMEGA = 2000.0  # rad/s: 10 m/s at the rim


def write(tmp_path, velocity: str, geometry: str = DISK):
    path = tmp_path / "case.toml"
    path.write_text(CASE.format(velocity=velocity, geometry=geometry))
    return path


def test_rigid_rotation_from_an_expression(tmp_path):
    case = load_case(write(tmp_path, f'["-{OMEGA} * y", "{OMEGA} * x"]'))
    state = build_problem(case).state
    x = state.position
    np.testing.assert_allclose(state.velocity, OMEGA * np.stack([-x[:, 1], x[:, 0]], axis=1),
                               rtol=1e-15, atol=1e-15)
    # a spinning disk keeps its angular momentum and its energy
    sim = Simulation(case)

    def angular(s):
        return float(np.sum(s.mass * (s.position[:, 0] * s.velocity[:, 1]
                                      - s.position[:, 1] * s.velocity[:, 0])))

    L0 = angular(sim.state)
    sim.run()
    assert angular(sim.state) == pytest.approx(L0, rel=1e-9)
    summary = sim.summary()
    assert abs(summary["total_energy_relative_error"]) < 1e-3
    assert summary["momentum_drift"] < 1e-12


def test_a_number_and_an_expression_mix(tmp_path):
    case = load_case(write(tmp_path, '[5.0, "sin(pi * x / 0.01)"]'))
    state = build_problem(case).state
    np.testing.assert_array_equal(state.velocity[:, 0], 5.0)
    np.testing.assert_allclose(state.velocity[:, 1], np.sin(np.pi * state.position[:, 0] / 0.01),
                               rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("suffix", ["csv", "npz"])
def test_velocity_and_temperature_from_a_particle_file(tmp_path, suffix):
    rng = np.random.default_rng(3)
    x = np.stack(np.meshgrid(np.arange(6) * 1e-3, np.arange(4) * 1e-3), axis=-1).reshape(-1, 2)
    v = rng.normal(size=x.shape)
    T = 300.0 + rng.random(x.shape[0]) * 100
    path = tmp_path / f"p.{suffix}"
    if suffix == "csv":
        rows = "\n".join(",".join(repr(float(c)) for c in (*xi, *vi, ti))
                         for xi, vi, ti in zip(x, v, T, strict=True))
        path.write_text("x,y,vx,vy,temperature\n" + rows + "\n")
    else:
        np.savez(path, position=x, velocity=v, temperature=T)
    geometry = f'type = "file"\npath = "{path}"\nspacing = 0.001'
    case = load_case(write(tmp_path, "[1.0, 0.0]", geometry))
    state = build_problem(case).state
    np.testing.assert_allclose(state.velocity, v + [1.0, 0.0], rtol=1e-15)
    np.testing.assert_allclose(state.material_state[:, TEMPERATURE], T, rtol=1e-15)


runner = CliRunner()


@pytest.mark.parametrize(("velocity", "field"), [
    ('["-1000 * y", "1000 * w"]', "bodies.0.velocity.1 = '1000 * w': uses w"),
    ('["-1000 * y", "1000 * x"]', None),
    ('["-1000 * (y", "0"]', "bodies.0.velocity.0 = '-1000 * (y'"),
    ('["-1000 * y", "1000 * z"]', "bodies.0.velocity.1 = '1000 * z': uses z"),
])
def test_bad_expressions_refused(tmp_path, velocity, field):
    res = runner.invoke(app, ["check", str(write(tmp_path, velocity))])
    if field is None:
        assert res.exit_code == 0, res.output
        return
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and field in lines[0], lines


def test_bad_file_columns_refused(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("x,y,vx,temperature\n0,0,1,300\n")
    geometry = f'type = "file"\npath = "{path}"\nspacing = 0.001'
    res = runner.invoke(app, ["check", str(write(tmp_path, "[0.0, 0.0]", geometry))])
    assert res.exit_code == 2 and "vx, vy" in res.output, res.output
    path.write_text("x,y,temperature\n0,0,-3\n")
    res = runner.invoke(app, ["check", str(write(tmp_path, "[0.0, 0.0]", geometry))])
    assert res.exit_code == 2 and "temperature" in res.output, res.output
