"""Rigid walls (ghost particles), clamped particles and the tip mass."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from impactsph.boundaries import FREE_SLIP, NO_SLIP, Walls, fill_ghosts, walls_of
from impactsph.loading import load_case, validate_case
from impactsph.problem import build_problem
from impactsph.simulation import Simulation

RHO, E = 7850.0, 2.0e11


def bar_on_wall(dim: int, slip: str = "free") -> dict:
    """A slender elastic bar moving at 10 m/s onto a rigid wall at y = 0 (x = 0 in 1D)."""
    dx, V = 1e-3, 10.0
    n_long = 100 if dim == 1 else 60
    c = math.sqrt(E / RHO)
    if dim == 1:
        body = {"name": "bar", "material": "m", "velocity": [-V],
                "geometry": {"origin": [0.0], "size": [n_long * dx], "spacing": dx}}
        mat = {"model": "bar", "density": RHO, "youngs_modulus": E}
    else:
        body = {"name": "bar", "material": "m", "velocity": [0.0, -V],
                "geometry": {"origin": [0.0, 0.0], "size": [3 * dx, n_long * dx],
                             "spacing": dx}}
        mat = {"model": "elastic", "density": RHO, "youngs_modulus": E}
    return {"name": "wallbar", "dimension": dim, "materials": {"m": mat}, "bodies": [body],
            "boundaries": [{"point": [0.0] * dim, "normal": [0.0] * (dim - 1) + [1.0],
                            "slip": slip}],
            "viscosity": {"alpha1": 0.3, "alpha2": 0.3},
            "time": {"end": 4 * n_long * dx / c}, "output": {"figures": False}}


@pytest.mark.parametrize("dim", [1, 2])
def test_elastic_bar_rebounds_from_the_wall(dim):
    """Bar theory: contact lasts 2L/c and the bar leaves at its impact speed.  Measured
    rebound 0.962 V (1D, 100 particles) and 0.963 V (2D, 3 x 60) with AV (0.3, 0.3), whose
    dissipation takes the rest, as between the colliding bars."""
    sim = Simulation(validate_case(bar_on_wall(dim)))
    y_wall_min = []
    sim.run(callback=lambda s: y_wall_min.append(s.state.position[:, -1].min()))
    s = sim.summary()
    m = sim.state.mass
    v_out = float(m @ sim.state.velocity[:, -1] / m.sum())
    assert v_out == pytest.approx(10.0, rel=0.05)
    assert s["total_energy_relative_error"] < 1e-3
    assert min(y_wall_min) > 0.0  # no particle ever reached the wall
    assert s["wall_constraint_events"] == 0
    # momentum changes by exactly the walls' impulse (AV is antisymmetric)
    assert s["momentum_drift"] < 1e-10
    assert sim.record.history[-1]["external_impulse_" + "xy"[dim - 1]] == pytest.approx(
        2 * 10.0 * m.sum(), rel=0.05)


def test_wall_constraint_stops_crossing():
    """A particle pushed behind the wall is put back on it and loses its velocity into it."""
    sim = Simulation(validate_case(bar_on_wall(2)))
    x = np.array([[0.0, -1e-4], [0.0, 2e-3]])
    v = np.array([[1.0, -5.0], [0.0, -5.0]])
    count, impulse = sim.walls.enforce(x, v, np.array([2.0, 3.0]))
    assert count == 1
    assert x[0, 1] == 0.0 and v[0, 1] == 0.0 and v[0, 0] == 1.0  # tangential kept
    assert v[1, 1] == -5.0  # the particle in front is untouched
    np.testing.assert_allclose(impulse, [0.0, 10.0])


def test_walls_from_plain_data_and_from_case_walls():
    """Walls take plain sequences; :func:`walls_of` reads anything with point, normal and slip
    (the case's pydantic walls, or simple namespaces) into the same arrays."""
    walls = Walls.from_planes([[0.0, 1.0], [2.0, 0.0]], [[0.0, 3.0], [-1.0, -1.0]],
                              ["free", "no"], 2)
    np.testing.assert_array_equal(walls.points, [[0.0, 1.0], [2.0, 0.0]])
    np.testing.assert_allclose(walls.normals, [[0.0, 1.0], [-math.sqrt(0.5)] * 2])
    np.testing.assert_array_equal(walls.kinds, [FREE_SLIP, NO_SLIP])
    assert len(Walls.from_planes([], [], [], 3)) == 0
    assert Walls.from_planes([], [], [], 3).points.shape == (0, 3)
    specs = [SimpleNamespace(point=[0.0, 1.0], normal=[0.0, 3.0], slip="free"),
             SimpleNamespace(point=[2.0, 0.0], normal=[-1.0, -1.0], slip="no")]
    again = walls_of(specs, 2)
    for name in ("points", "normals", "kinds"):
        np.testing.assert_array_equal(getattr(again, name), getattr(walls, name))
    case = validate_case(bar_on_wall(2, slip="no"))
    from_case = walls_of(case.boundaries, 2)
    np.testing.assert_array_equal(from_case.normals, [[0.0, 1.0]])
    np.testing.assert_array_equal(from_case.kinds, [NO_SLIP])


@pytest.mark.parametrize("slip", ["free", "no"])
def test_ghost_velocity_follows_the_slip_kind(slip):
    """Free slip mirrors the normal velocity only; no slip mirrors the whole velocity."""
    walls = Walls.from_planes([[0.0, 0.0]], [[0.0, 1.0]], [slip], 2)
    x = np.zeros((2, 2))
    x[0] = [0.3, 0.2]
    v = np.zeros((2, 2))
    v[0] = [1.0, -2.0]
    S = np.zeros((2, 3, 3))
    rho, e, m, h = np.ones(2), np.ones(2), np.ones(2), np.ones(2)
    material, body = np.zeros(2, np.int32), np.zeros(2, np.int32)
    fill_ghosts(np.array([0]), np.array([0]), walls.points, walls.normals, walls.kinds, 1,
                x, v, rho, e, S, np.zeros((2, 5)), m, h, material, body, 1)
    np.testing.assert_array_equal(x[1], [0.3, -0.2])
    np.testing.assert_array_equal(v[1], [1.0, 2.0] if slip == "free" else [-1.0, 2.0])
    assert body[1] == 1


def cantilever_case(n_long: int = 60, tip_speed: float = 1.0, t_end: float = 1e-3) -> dict:
    dx = 1e-3
    return {
        "name": "beam", "dimension": 2,
        "materials": {"m": {"model": "elastic", "density": RHO, "youngs_modulus": E}},
        "bodies": [{"name": "beam", "material": "m", "velocity": [0.0, 0.0],
                    "geometry": {"origin": [-3 * dx, -2.5 * dx],
                                 "size": [(n_long + 3) * dx, 5 * dx], "spacing": dx},
                    "clamped": {"origin": [-3.5 * dx, -3 * dx], "size": [3.5 * dx, 6 * dx]},
                    "tip_mass": {"mass": 1e-6, "depth": 1.0, "velocity": [0.0, tip_speed],
                                 "region": {"origin": [(n_long - 1) * dx, -3 * dx],
                                            "size": [dx, 6 * dx]}}}],
        "kernel": {"h_over_dx": 1.3},
        "viscosity": {"alpha1": 0.1, "alpha2": 0.1},
        "time": {"end": t_end}, "output": {"figures": False},
    }


def test_clamped_particles_never_move_and_tip_mass_momentum():
    case = validate_case(cantilever_case(n_long=20, tip_speed=50.0, t_end=2e-5))
    problem = build_problem(case)
    s = problem.state
    clamped = s.clamped.copy()
    assert clamped.sum() == 15  # 3 columns x 5 rows behind the root
    tip = s.velocity[:, 1] != 0
    assert tip.sum() == 5
    # momentum of the tip mass shared with the particles it lands on: G V0 = (G + M) v
    extra = 1e-6
    own = s.mass[tip].sum()  # carried as added inertia (the default): the masses are the lattice's
    assert s.added_mass[tip].sum() == pytest.approx(extra)
    assert not s.added_mass[~tip].any()
    assert s.velocity[tip, 1] == pytest.approx(50.0 * extra / (extra + own))
    x0 = s.position[clamped].copy()
    sim = Simulation(case, problem)
    sim.run(callback=lambda q: np.testing.assert_array_equal(q.state.velocity[clamped], 0.0))
    np.testing.assert_array_equal(sim.state.position[clamped], x0)
    assert sim.summary()["momentum_drift"] < 1e-10  # the clamp's impulse is booked


def test_elastic_cantilever_first_mode_frequency():
    """A clamped elastic beam, L = 60 mm, 5 mm deep, with its tip given 1 m/s, swings at the
    Euler-Bernoulli first-mode frequency omega = 1.875^2 sqrt(E' I / (rho A L^4)),
    E' = E/(1 - nu^2) in plane strain: measured from the first return of the tip to its
    starting position (half a period)."""
    L, depth, nu = 60e-3, 5e-3, 0.3
    E_ps = E / (1 - nu**2)
    omega = 1.8751**2 * math.sqrt(E_ps * depth**3 / 12 / (RHO * depth * L**4))
    period = 2 * math.pi / omega
    case = validate_case(cantilever_case(n_long=60, tip_speed=1.0, t_end=0.6 * period))
    sim = Simulation(case)
    tip = sim.state.velocity[:, 1] > 0
    times, disp = [], []

    def record(q):
        times.append(q.state.time)
        disp.append(float(np.mean(q.state.position[tip, 1] - q.state.initial_position[tip, 1])))

    sim.run(callback=record)
    times, disp = np.array(times), np.array(disp)
    peak = int(np.argmax(disp))
    assert disp[peak] > 0
    after = np.flatnonzero(disp[peak:] <= 0)
    assert after.size, "the tip never came back"
    k = peak + after[0]
    t_zero = times[k - 1] + (times[k] - times[k - 1]) * disp[k - 1] / (disp[k - 1] - disp[k])
    assert 2 * t_zero == pytest.approx(period, rel=0.10)


def test_builtin_2d_cases_set_up_as_the_paper_says():
    taylor = build_problem(load_case("taylor")).state
    assert taylor.n == 21 * 67
    assert np.allclose(taylor.velocity, [0.0, -200.0])
    cant = build_problem(load_case("cantilever"))
    assert cant.state.n == 204 * 5
    assert cant.state.clamped.sum() == 15
    # 25 tip particles at V0 G / (G + M): 232 m/s with our particles (the paper: 241.1)
    assert cant.info["tip_initial_speed"] == pytest.approx(232.0, abs=1.0)
    assert np.sum(cant.state.velocity[:, 1] < 0) == 25
