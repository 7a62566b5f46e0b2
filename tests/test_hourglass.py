"""The hourglass control (``stabilisation.hourglass = zeta``; docs/stabilisation.md).

It acts on the relative motion of neighbours that their velocity gradients do not explain:
none for a linear velocity field (with the gradient correction, which makes the gradient of a
linear field exact), against a zig-zag field, which the collocated SPH gradient does not see at
all; its pair terms are antisymmetric (momentum to round-off) and its power is booked in the
internal energy (total energy to the time integration's error)."""

from __future__ import annotations

import numpy as np

from impactsph import Simulation
from impactsph.loading import validate_case

A = np.array([[0.7, -0.4], [1.1, 0.3]])


def block(hourglass: float, correction: str = "velocity_gradient", jitter: float = 0.2,
          side: int = 9) -> Simulation:
    case = validate_case({
        "name": "hourglass", "dimension": 2,
        "materials": {"m": {"model": "elastic", "density": 7850.0, "youngs_modulus": 208e9}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0],
                    "geometry": {"origin": [0.0, 0.0], "size": [side * 1e-3] * 2,
                                 "spacing": 1e-3}}],
        "kernel": {"h_over_dx": 1.3},
        "stabilisation": {"gradient_correction": correction, "hourglass": hourglass},
        "viscosity": {"alpha1": 0.0, "alpha2": 0.0},
        "time": {"end": 1e-6}, "output": {"figures": False}})
    sim = Simulation(case)
    if jitter:
        rng = np.random.default_rng(7)
        sim.state.position += rng.uniform(-jitter, jitter, sim.state.position.shape) * 1e-3
    return sim


def test_a_linear_field_is_left_alone():
    """With the gradient correction the velocity gradient of a linear field is exact, so the
    control's rate and push are round-off: below 1e-9 of their scale for a motion of that
    speed, ``zeta (mu / rho) |v| / dx^2`` (times ``tau = h / c_shear`` for the push)."""
    sim = block(1.0)
    s = sim.state
    s.velocity[:] = s.position @ A.T
    dv, _, _, _, dhg = (np.array(r[: s.n]) for r in sim.solver.rates(s))
    reference = block(0.0)
    reference.state.velocity[:] = reference.state.position @ A.T
    dv0 = reference.solver.rates(reference.state)[0][: s.n]
    mu, rho, dx = 208e9 / 2.6, 7850.0, 1e-3
    scale = (mu / rho) * np.abs(s.velocity).max() / dx**2
    tau = 1.3 * dx / np.sqrt(mu / rho)
    assert np.abs(dhg).max() < 1e-9 * scale
    assert np.abs(dv - dv0).max() < 1e-9 * scale * tau


def test_a_zig_zag_is_resisted():
    """Rows sliding alternately (+u, -u along x, the beam's hourglass mode): the control's
    rate opposes the motion at every interior particle."""
    sim = block(1.0, jitter=0.0)
    s = sim.state
    row = np.rint(s.position[:, 1] / 1e-3 - 0.5).astype(int)
    s.velocity[:, 0] = np.where(row % 2 == 0, 1.0, -1.0)
    dhg = sim.solver.rates(s)[4][: s.n]
    interior = np.all((s.position > 2.5e-3) & (s.position < 6.5e-3), axis=1)
    assert interior.sum() > 0
    assert np.all(dhg[interior, 0] * s.velocity[interior, 0] < 0)
    assert np.abs(dhg[interior, 1]).max() < 1e-6 * np.abs(dhg[interior, 0]).max()


def run(courant: float) -> tuple[float, float]:
    """A jittered block in random motion for 20 us: (momentum change over sum m |v|,
    relative total-energy change)."""
    sim = block(1.0, jitter=0.1)
    sim.case.time.courant = courant
    s = sim.state
    s.velocity[:] = np.random.default_rng(3).normal(0.0, 0.05, s.velocity.shape)
    p0, e0 = s.momentum(), s.kinetic_energy() + s.internal_energy()
    scale = float(s.mass @ np.linalg.norm(s.velocity, axis=1))
    sim.run(t_end=20e-6)
    assert np.abs(s.hourglass_acceleration).max() > 0
    e1 = s.kinetic_energy() + s.internal_energy()
    return float(np.abs(s.momentum() - p0).max() / scale), abs(e1 - e0) / e0


def test_momentum_and_energy_are_kept():
    drift_coarse, energy_coarse = run(0.3)
    drift_fine, energy_fine = run(0.15)
    assert max(drift_coarse, drift_fine) < 1e-12
    assert energy_fine < energy_coarse / 4.0
