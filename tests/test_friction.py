"""Coulomb friction on a rigid wall: a block striking a wall obliquely, sliding throughout,
is slowed along the wall by mu times the wall's normal impulse; the friction's work is heat,
so the total energy is kept."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case

CASE = """
name = "oblique_block"
dimension = 2

[materials.steel]
model = "elastic"
density = 7850.0
youngs_modulus = 200e9
poisson_ratio = 0.3

[[bodies]]
name = "block"
material = "steel"
velocity = [20.0, -10.0]
[bodies.geometry]
origin = [0.0, 0.0]
size = [0.004, 0.004]
spacing = 0.0005

[[boundaries]]
type = "wall"
point = [0.0, 0.0]
normal = [0.0, 1.0]
friction = {mu}

[kernel]
h_over_dx = 1.3

[viscosity]
alpha1 = 0.5
alpha2 = 0.5

[time]
end = 4e-6

[output]
figures = false
"""


def run(tmp_path, mu: float) -> Simulation:
    path = tmp_path / f"block-{mu}.toml"
    path.write_text(CASE.format(mu=mu))
    sim = Simulation(load_case(path))
    sim.run()
    return sim


@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_oblique_impact_follows_coulomb(tmp_path, mu):
    sim = run(tmp_path, mu)
    h = sim.record.history[-1]
    normal, along = h["external_impulse_y"], h["external_impulse_x"]
    assert normal > 0  # the wall pushed the block back
    # the block slid throughout (its speed along the wall stays well above zero), so the
    # tangential impulse is -mu times the normal one
    vx = sim.state.velocity[:, 0]
    assert vx.min() > 5.0
    assert -along / normal == pytest.approx(mu, rel=1e-3), (-along / normal, mu)
    s = sim.summary()
    assert abs(s["total_energy_relative_error"]) < 1e-3
    assert s["momentum_drift"] < 1e-9  # the wall's impulse, friction included, is booked


def test_frictionless_wall_keeps_the_sliding_momentum(tmp_path):
    sim = run(tmp_path, 0.0)
    h = sim.record.history[-1]
    assert abs(h["external_impulse_x"]) < 1e-9 * h["external_impulse_y"]
    frictional = run(tmp_path, 0.3)
    # friction heats: the block keeps less kinetic energy and gains internal energy
    assert frictional.summary()["kinetic_energy_final"] < sim.summary()["kinetic_energy_final"]
    assert frictional.record.history[-1]["internal_energy"] > h["internal_energy"]
    assert np.isfinite(frictional.state.velocity).all()
