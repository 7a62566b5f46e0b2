"""Elastic wave speeds: a 1D bar (sqrt(E/rho)) and a 2D plane-strain block
(sqrt((K + 4/3 mu)/rho))."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactsph.kernels import gradient_moment
from impactsph.loading import validate_case
from impactsph.simulation import Simulation

RHO, E, NU = 7850.0, 2.0e11, 0.3


def block_case(dim: int, size: list[float], dx: float, model: str, t_end: float,
               h_over_dx: float = 1.2) -> dict:
    return {
        "name": f"wave{dim}d", "dimension": dim,
        "materials": {"steel": {"model": model, "density": RHO, "youngs_modulus": E,
                                "poisson_ratio": NU}},
        "bodies": [{"name": "block", "material": "steel", "velocity": [0.0] * dim,
                    "geometry": {"origin": [0.0] * dim, "size": size, "spacing": dx}}],
        "viscosity": {"alpha1": 0.3, "alpha2": 0.3},
        "kernel": {"h_over_dx": h_over_dx},
        # the plain SPH gradient, whose discrete moment these tests measure
        "stabilisation": {"gradient_correction": "none", "hourglass": 0.0},
        "time": {"end": t_end, "wave_speed": "p_wave" if dim > 1 else "bar"},
        "output": {"figures": False},
    }


def front_position(X: np.ndarray, v: np.ndarray, level: float) -> float:
    """Largest X where the velocity profile (sorted by X) crosses ``level`` going down."""
    order = np.argsort(X)
    X, v = X[order], v[order]
    k = np.flatnonzero((v[:-1] >= level) & (v[1:] < level))[-1]
    return float(X[k] + (level - v[k]) * (X[k + 1] - X[k]) / (v[k + 1] - v[k]))


def measure_speed(sim: Simulation, select: np.ndarray, level: float, t1: float, t2: float
                  ) -> float:
    X = sim.state.initial_position[select, 0]
    sim.run(t_end=t1)
    x1 = front_position(X, sim.state.velocity[select, 0], level)
    sim.run(t_end=t2)
    x2 = front_position(X, sim.state.velocity[select, 0], level)
    return (x2 - x1) / (t2 - t1)


@pytest.mark.parametrize("h_over_dx", [1.0, 1.2, 2.0])
def test_bar_wave_speed_1d(h_over_dx):
    """A velocity step V in a long bar launches a front of amplitude V/2 that travels at
    sqrt(E/rho) in the material (Lagrangian) coordinate.  The SPH gradient of a linear field
    is off by the kernel's discrete moment, which depends on h/dx alone (1.022 at the paper's
    h = 1.2 dx): the wave travels at moment * c, and at c within 1% where the moment is 1."""
    dx, n = 1e-4, 1500
    sim = Simulation(validate_case(block_case(1, [n * dx], dx, "bar", 1.0, h_over_dx)))
    V = 1.0
    sim.state.velocity[sim.state.position[:, 0] < 100 * dx, 0] = V
    c = math.sqrt(E / RHO)
    t1, t2 = 300 * dx / c, 1100 * dx / c
    speed = measure_speed(sim, np.ones(sim.state.n, bool), 0.25 * V, t1, t2)
    moment = gradient_moment(h_over_dx, 1)
    assert speed == pytest.approx(moment * c, rel=0.003)
    if abs(moment - 1.0) < 1e-9:
        assert speed == pytest.approx(c, rel=0.01)


def test_p_wave_speed_plane_strain_2d():
    """The same in a wide 2D plane-strain block, on its centre line, before the release
    waves from the free sides reach it: sqrt((K + 4/3 mu)/rho)."""
    dx = 1e-4
    nx, ny = 190, 160
    sim = Simulation(validate_case(block_case(2, [nx * dx, ny * dx], dx, "elastic", 1.0)))
    V = 1.0
    sim.state.velocity[sim.state.position[:, 0] < 30 * dx, 0] = V
    K = E / (3 * (1 - 2 * NU))
    mu = E / (2 * (1 + NU))
    c = math.sqrt((K + 4.0 / 3.0 * mu) / RHO)
    y = sim.state.position[:, 1]
    centre = np.abs(y - 0.5 * ny * dx) < 0.6 * dx  # the two rows either side of the centre
    t1, t2 = 50 * dx / c, 140 * dx / c
    speed = measure_speed(sim, centre, 0.25 * V, t1, t2)
    assert speed == pytest.approx(c, rel=0.02)
    assert speed == pytest.approx(gradient_moment(1.2, 2) * c, rel=0.01)
