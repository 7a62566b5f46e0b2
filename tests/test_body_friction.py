"""Coulomb friction between bodies (``[contact] friction``, issue 14): each pair's friction is
antisymmetric and dissipative, its work booked as heat (momentum and energy exact in the rates
of a random two-body cloud); a block striking a plate obliquely, sliding throughout, receives
from the friction a tangential impulse mu times the normal one, at two spacings."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case

CASE = """
name = "oblique_block_on_plate"
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
origin = [0.0, @DX@]
size = [0.004, 0.004]
spacing = @DX@

[[bodies]]
name = "plate"
material = "steel"
velocity = [0.0, 0.0]
clamped = {origin = [-0.011, -0.0041], size = [0.032, 0.0011]}
[bodies.geometry]
origin = [-0.01, -0.004]
size = [0.03, 0.004]
spacing = @DX@

[contact]
friction = @MU@

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


def simulation(tmp_path, mu: float, dx: float = 0.0005, traction: str = "normal_stress"
               ) -> Simulation:
    path = tmp_path / f"block-{mu}-{dx}-{traction}.toml"
    path.write_text(CASE.replace("@MU@", repr(mu)).replace("@DX@", repr(dx))
                    .replace("[contact]\n", f'[contact]\ntraction = "{traction}"\n'))
    return Simulation(load_case(path))


@pytest.mark.parametrize("traction", ["normal_stress", "pressure"])
def test_friction_keeps_momentum_and_books_its_work_as_heat(tmp_path, traction):
    """The rates with friction less those without, on the two bodies pressed together with
    random velocities: the friction forces sum to zero (to round-off), their power is
    negative, and the heat they add equals the kinetic energy they remove."""
    rng = np.random.default_rng(3)
    rates = {}
    for mu in (0.0, 0.4):
        sim = simulation(tmp_path, mu, traction=traction)
        s = sim.state
        s.position[s.body == 0, 1] -= 0.3 * 0.0005  # the block pressed into the plate
        s.velocity[:] = rng.normal(0.0, 10.0, s.velocity.shape)
        s.density *= 1.0 + 1e-3  # compressed: the pairs push
        rng = np.random.default_rng(3)
        dv, _, de, _, _ = sim.solver.rates(s)
        rates[mu] = (dv[: s.n].copy(), de[: s.n].copy())
    friction = rates[0.4][0] - rates[0.0][0]
    heat = rates[0.4][1] - rates[0.0][1]
    m, v = s.mass, s.velocity
    force = m[:, None] * friction
    assert np.abs(force).sum() > 0  # friction acts
    assert np.abs(force.sum(axis=0)).max() <= 1e-12 * np.abs(force).sum()
    power = float((force * v).sum())
    assert power < 0.0
    assert float((m * heat).sum()) == pytest.approx(-power, rel=1e-10)
    assert (heat >= 0.0).all()


def impulses(tmp_path, mu: float, dx: float) -> tuple[float, float, Simulation]:
    """The block's momentum change along and normal to the plate over the run."""
    sim = simulation(tmp_path, mu, dx)
    s = sim.state
    block = s.body == 0
    before = (s.mass[block, None] * s.velocity[block]).sum(axis=0)
    sim.run()
    after = (s.mass[block, None] * s.velocity[block]).sum(axis=0)
    assert s.velocity[block, 0].min() > 10.0  # it slid throughout
    change = after - before
    return float(change[0]), float(change[1]), sim


def test_oblique_impact_on_a_plate_follows_coulomb(tmp_path):
    """The friction's tangential impulse (the run with friction less the frictionless one,
    which itself gets 5% of the normal impulse from the artificial viscosity across the
    interface) is mu times the normal impulse: measured +1.3% (mu = 0.1) and +2.3% (0.3)
    at dx = 0.5 mm."""
    for dx in (0.0005, 0.00025):
        free_along, _, _ = impulses(tmp_path, 0.0, dx)
        along, normal, sim = impulses(tmp_path, 0.3, dx)
        assert normal > 0.0
        assert (free_along - along) / normal == pytest.approx(0.3, rel=0.04), dx
        summary = sim.summary()
        assert abs(summary["total_energy_relative_error"]) < 1e-4
        assert summary["momentum_drift"] < 1e-12
