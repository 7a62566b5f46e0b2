"""The time integrators (``time.integrator``, :mod:`impactsph.integrate`): each step is the
Runge-Kutta method it claims to be, and the three-stage one keeps the energy of the
low-viscosity switches where the midpoint step lets it grow (docs/dissipation.md, "The
switches' energy errors")."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.integrate import INTEGRATORS

#: the stability polynomial R(w) of each method: y_{n+1} = R(lambda dt) y_n for y' = lambda y
POLYNOMIAL = {
    "midpoint": lambda w: 1 + w + w**2 / 2,
    "ssp_rk3": lambda w: 1 + w + w**2 / 2 + w**3 / 6,
}


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_a_step_is_the_method_on_an_oscillator(name):
    """Every particle of the bars bound to its start by a spring, ``dv/dt = -omega^2 (x -
    x0)`` (density, energy and stress rates zero): ``u = (x - x0) + i v / omega`` obeys ``u' =
    -i omega u``, so after n steps of ``dt`` it is ``R(-i omega dt)^n u(0)``, R the method's
    stability polynomial (the midpoint step's ``|R|^2 = 1 + z^4/4`` grows; the SSP-RK3's
    ``1 - z^4/12 + z^6/36`` decays).  To 1e-12 of the amplitude, 60 steps at ``z = 0.6``."""
    sim = Simulation(load_case("bars", ["bodies.0.velocity=[0.0]", "bodies.1.velocity=[0.0]"]))
    state = sim.state
    n = state.n
    omega, z = 1.0e7, 0.6
    dt = z / omega
    x0 = state.position.copy()
    rng = np.random.default_rng(3)
    state.velocity[:] = 1e5 * rng.normal(size=state.velocity.shape)  # amplitudes of 1 cm
    u0 = 0.0 + 1j * state.velocity[:, 0] / omega
    dv = np.zeros((n, 1))
    zeros = (np.zeros(n), np.zeros(n), np.zeros((n, 6)), np.zeros((n, 0)))

    def rates(s, time=None):
        dv[:] = -omega**2 * (s.position - x0)
        return (dv, *zeros)

    integrator = INTEGRATORS[name](rates, sim.problem.table, n, state.dim)
    steps = 60
    for _ in range(steps):
        integrator.step(state, dt)
    u = (state.position[:, 0] - x0[:, 0]) + 1j * state.velocity[:, 0] / omega
    expected = POLYNOMIAL[name](-1j * z) ** steps * u0
    assert np.abs(u - expected).max() <= 1e-12 * np.abs(u0).max()
    grew = np.abs(u).sum() > np.abs(u0).sum()
    assert grew if name == "midpoint" else not grew


def _bars(integrator: str, courant: float) -> tuple[dict, np.ndarray, np.ndarray]:
    sim = Simulation(load_case("bars", [
        'viscosity.scheme="cullen_dehnen"', "viscosity.alpha1=1.0", "viscosity.alpha2=2.0",
        f'time.integrator="{integrator}"', f"time.courant={courant}"]))
    sim.run()
    h = sim.record.history
    t = np.array([r["time"] for r in h])
    energy = np.array([r["total_energy"] for r in h])
    return sim.summary(), t, (energy - energy[0]) / energy[0]


def test_ssp_rk3_keeps_the_energy_of_the_cullen_dehnen_bars():
    """Cullen & Dehnen's switch leaves the bars nearly without viscosity away from the
    fronts.  With the midpoint step at the case's Courant number 0.3 the total energy grows
    all run long, by a factor of 11 in the second half (measured: +4.5e-4 at 25 us, +5.0e-3 at
    50 us); with SSP-RK3 at 0.45 (the same number of rate evaluations) it stays within 1e-3
    and does not grow (measured -1.4e-4 at 25 us, -6.1e-4 at 50 us: the little viscosity
    left dissipates what the integrator no longer adds); momentum to round-off with both."""
    mid, t_mid, e_mid = _bars("midpoint", 0.3)
    rk3, t_rk3, e_rk3 = _bars("ssp_rk3", 0.45)
    half = t_mid[-1] / 2
    assert e_mid[-1] > 4 * e_mid[np.searchsorted(t_mid, half)] > 0  # the growth
    assert mid["total_energy_relative_error"] > 1e-3
    assert rk3["total_energy_relative_error"] <= 1e-3
    assert e_rk3[-1] <= e_rk3[np.searchsorted(t_rk3, half)] <= 0
    assert mid["momentum_drift"] <= 1e-12 and rk3["momentum_drift"] <= 1e-12
    # the same physics: the kinetic energy kept agrees to 0.5%
    assert rk3["kinetic_energy_ratio_final"] == pytest.approx(
        mid["kinetic_energy_ratio_final"], rel=5e-3)


def test_ssp_rk3_books_the_walls_impulse():
    """The paper's Taylor bar with Cullen & Dehnen's switch reaches the wall (the built-in case
    has no wall layer): the constraint's impulse on each stage's state is booked with that
    state's share in the step, so the momentum balance against the walls' impulse holds to
    round-off."""
    sim = Simulation(load_case("taylor", [
        'viscosity.scheme="cullen_dehnen"', "viscosity.alpha1=1.0", "viscosity.alpha2=2.0",
        'time.integrator="ssp_rk3"', "time.courant=0.45", "time.end=2e-5"]))
    sim.run()
    s = sim.summary()
    assert s["wall_constraint_events"] > 0
    assert s["momentum_drift"] <= 1e-12
    assert s["total_energy_relative_error"] <= 1e-3


def test_ssp_rk3_refuses_the_optimised_correction():
    """``ac_optimised`` optimises each factor over the time to the next evaluation, which the
    three-stage step does not give: the case is refused in one line naming both fields."""
    with pytest.raises(Exception, match="time.integrator = 'ssp_rk3' with viscosity.scheme = "
                                        "'ac_optimised'"):
        load_case("bars", ['time.integrator="ssp_rk3"', 'viscosity.scheme="ac_optimised"'])


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_the_history_contact_force_is_the_steps_impulse(name):
    """The bars, every step a history row: the sum of ``dt`` times the left bar's
    ``contact_force_left_x`` is its momentum change, to round-off (the row holds the step's
    mean force by the integrator's weights, not its last evaluation's, which with SSP-RK3 is
    a third of the way into the step)."""
    courant = "0.45" if name == "ssp_rk3" else "0.3"
    sim = Simulation(load_case("bars", [f'time.integrator="{name}"', f"time.courant={courant}",
                                        "time.end=1.5e-5", "output.history_every=1"]))
    left = sim.state.body == 0
    p0 = float(sim.state.mass[left] @ sim.state.velocity[left, 0])
    sim.run()
    p1 = float(sim.state.mass[left] @ sim.state.velocity[left, 0])
    rows = sim.record.history[1:]
    impulse = sum(r["dt"] * r["contact_force_left_x"] for r in rows)
    assert abs(p1 - p0) > 0.1 * abs(p0)  # the bars have met
    assert abs(impulse - (p1 - p0)) <= 1e-10 * abs(p0)


def test_the_combination_is_numpys_to_the_bit():
    """The SSP-RK3 step's convex combination of every integrated field
    (:func:`impactsph.integrate.combine_kept`, one compiled loop) gives what numpy's ``y *= 1 -
    w; y += w * y0`` gives, to the bit, the kept deviator as its six components: two
    products and a sum, not a fused multiply-add (which would change the last bits)."""
    from impactsph.integrate import combine_kept
    from impactsph.physics.stress_rate import symmetric_full, symmetric_upper

    rng = np.random.default_rng(7)
    n, dim, width = 257, 2, 9
    shapes = [(n, dim), (n, dim), (n,), (n,), (n, 3, 3), (n,), (n, width), (n, dim)]
    fields = [rng.normal(size=s) * 10.0 ** rng.integers(-8, 9) for s in shapes]
    fields[4] = 0.5 * (fields[4] + fields[4].transpose(0, 2, 1))  # a symmetric deviator
    kept = [rng.normal(size=s) * 10.0 ** rng.integers(-8, 9) for s in shapes]
    kept[4] = symmetric_upper(0.5 * (kept[4] + kept[4].transpose(0, 2, 1)))
    for weight in (0.75, 1.0 / 3.0):
        expected = []
        for y, k in zip(fields, kept, strict=True):
            y = y.copy()
            y *= 1.0 - weight
            y += weight * (symmetric_full(k) if y.ndim == 3 else k)
            expected.append(y)
        got = [y.copy() for y in fields]
        combine_kept(weight, *got, *kept)
        for a, b in zip(got, expected, strict=True):
            assert np.array_equal(a, b)
        # no hourglass columns (the control off): the other fields the same
        got = [y.copy() for y in fields[:7]] + [np.zeros((n, 0))]
        combine_kept(weight, *got, *kept[:7], np.zeros((n, 0)))
        for a, b in zip(got[:7], expected[:7], strict=True):
            assert np.array_equal(a, b)


def _all_columns_kept(monkeypatch) -> None:
    """The step's start copy keeps every column of the case's material state."""
    from impactsph import integrate

    monkeypatch.setattr(integrate, "material_state_kept", lambda options, width, heats=True: width)


def _same_state(a: Simulation, b: Simulation) -> None:
    for key, value in a.state.arrays().items():
        assert np.array_equal(value, b.state.arrays()[key]), key


@pytest.mark.parametrize("name, overrides", [
    ("bars", []),  # elastic (1D)
    ("bars", ['time.integrator="ssp_rk3"']),  # and SSP-RK3's second copy
    ("rings", []),  # elastic, plane strain, two bodies
])
def test_an_elastic_runs_start_copy_keeps_no_material_state(name, overrides, monkeypatch):
    """Where no stage can change the material state (an elastic run in 1D, plane strain or
    3D: :func:`impactsph.integrate.material_state_kept`) the step's start copy keeps none of
    its columns (40 bytes a particle), and the run gives the same bits as with them kept: no
    column of its state moves."""
    case = load_case(name, [*overrides, "time.max_steps=6"])
    sim = Simulation(case)
    start = sim.state.material_state.copy()
    sim.run()
    copies = [sim.integrator._start] + ([sim.integrator._y1] if overrides else [])
    assert [c.material_state.shape for c in copies] == [(sim.state.n, 0)] * len(copies)
    assert np.array_equal(sim.state.material_state, start)  # nothing moves it
    _all_columns_kept(monkeypatch)
    full = Simulation(case)
    full.run()
    assert full.integrator._start.material_state.shape == start.shape
    _same_state(sim, full)


HEATING = ["materials.iron.specific_heat=452.0"]  # beta / c_p: the plastic work heats


@pytest.mark.parametrize("integrator, heating", [("midpoint", []), ("ssp_rk3", []),
                                                 ("midpoint", HEATING)],
                         ids=["midpoint", "ssp_rk3", "heating"])
def test_a_plastic_runs_start_copy_keeps_the_return_maps_columns(integrator, heating,
                                                                  monkeypatch):
    """A return map without a damage model, plane stress or axisymmetry changes the first
    columns of the material state only: the plastic strain and its rate, and the temperature
    where its material heats (a specific heat given).  The start copy keeps those, two or
    three columns, not the others (24 or 16 bytes a particle), and the run gives the same
    bits as with every column kept.  The Taylor bar's impact face yields within its first
    steps, so the kept columns do move; its iron has no specific heat, so its temperature
    stays unless one is given."""
    from impactsph.models.columns import (
        EQUIVALENT_PLASTIC_STRAIN,
        PLASTIC_COLUMNS,
        RETURN_MAP_COLUMNS,
        TEMPERATURE,
    )

    case = load_case("taylor", [f'time.integrator="{integrator}"', "time.max_steps=12",
                                *heating])
    kept = RETURN_MAP_COLUMNS if heating else PLASTIC_COLUMNS
    assert (RETURN_MAP_COLUMNS, PLASTIC_COLUMNS) == (3, 2)
    sim = Simulation(case)
    start = sim.state.material_state.copy()
    sim.run()
    copies = [sim.integrator._start] + ([sim.integrator._y1] if integrator == "ssp_rk3"
                                        else [])
    assert [c.material_state.shape for c in copies] == [(sim.state.n, kept)] * len(copies)
    assert (sim.state.material_state[:, EQUIVALENT_PLASTIC_STRAIN] > 0.0).any()
    # the temperature moves where the material heats
    assert (sim.state.material_state[:, TEMPERATURE] > start[:, TEMPERATURE]).any() \
        == bool(heating)
    # the columns left out of the copy never move
    assert np.array_equal(sim.state.material_state[:, kept:], start[:, kept:])
    _all_columns_kept(monkeypatch)
    full = Simulation(case)
    full.run()
    assert full.integrator._start.material_state.shape == start.shape
    _same_state(sim, full)


def test_the_start_copy_keeps_the_material_state_where_a_model_changes_it():
    """A damage model, plane stress (the thickness ratio) or axisymmetry (the radius) keeps
    the whole material state in the start copy, a return map alone its first three
    columns where its material heats and two where it does not, and an elastic run none;
    the run's copy has that width."""
    from impactsph.integrate import material_state_kept
    from impactsph.models import STRENGTH
    from impactsph.physics.options import PassOptions
    from impactsph.preflight import state_kept, state_width

    plastic = (list(STRENGTH).index(STRENGTH["elastic_plastic"]),)
    assert material_state_kept(PassOptions(strength_kinds=(), damage_kinds=(1,)), 9) == 9
    assert material_state_kept(PassOptions(strength_kinds=plastic, damage_kinds=()), 5) == 3
    assert material_state_kept(PassOptions(strength_kinds=plastic, damage_kinds=()), 5,
                               heats=False) == 2
    assert material_state_kept(PassOptions(strength_kinds=plastic, damage_kinds=(),
                                           plane_stress=True), 5, heats=False) == 5
    assert material_state_kept(PassOptions(strength_kinds=plastic, damage_kinds=(),
                                           plane_stress=True), 5) == 5
    assert material_state_kept(PassOptions(strength_kinds=(), damage_kinds=()), 5) == 0
    taylor = "taylor"
    elastic = 'materials.iron.model="elastic"'
    damage = ['materials.iron.damage="johnson_cook_damage"',
              "materials.iron.johnson_cook_damage={d1=0.05, d2=3.44, d3=-2.12}"]
    assert state_kept(load_case(taylor)) == 2  # the paper's iron: no specific heat
    assert state_kept(load_case(taylor, HEATING)) == 3
    assert state_kept(load_case(taylor, [elastic, 'two_dimensional="plane_stress"'])) == 5
    assert state_kept(load_case("taylor_axisymmetric", [elastic])) == 5
    assert state_kept(load_case(taylor, [elastic])) == 0
    assert state_kept(load_case("rings")) == 0
    with_damage = load_case(taylor, [*damage, "time.max_steps=2"])
    assert state_kept(with_damage) == state_width(with_damage) > 5
    sim = Simulation(with_damage)
    sim.run()
    assert sim.integrator._start.material_state.shape == (sim.state.n, state_width(with_damage))
