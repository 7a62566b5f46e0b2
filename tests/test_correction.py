"""The acceleration correction (AC): the correction kernel on constructed fields, the energy
budget, and AC's imbalance and momentum drift in the summary."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from impactsph.kernels import cubic_spline
from impactsph.models.viscosity.correction import (
    VARIANTS,
    surviving_fraction,
)
from impactsph.neighbours import NeighbourList
from impactsph.physics.rates import correction_only

DX = 1e-3
H = 1.2 * DX


def lattice(dim: int, n: int) -> np.ndarray:
    axis = (np.arange(n) + 0.5) * DX
    return np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)


def apply_correction(x, u, variant, v=None, energy="work", h_ratio=0.5):
    """``u - u_corr`` and the energy term from the solver's own correction pass."""
    n, dim = x.shape
    nl = NeighbourList.build(x, 2 * H)
    m = np.full(n, 7800.0 * DX**dim)
    rho = np.full(n, 7800.0)
    v = np.zeros((n, dim)) if v is None else v
    viscosity = SimpleNamespace(scheme="ac", epsilon=0.01, correction=variant,
                                energy_correction=energy, correction_h_ratio=h_ratio)
    dv_corr, de_corr = correction_only(x, v, m, rho, np.full(n, H), np.zeros(n, np.int32), nl,
                                       u, viscosity)
    return u + dv_corr, de_corr


def interior(x, dim, n, margin=2):
    return np.all((x > margin * DX) & (x < (n - margin) * DX), axis=1)


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("mode,h_ratio", [("uniform", 0.5), ("2dx", 0.5), ("uniform", 0.8333),
                                          ("2dx", 0.8333)])
def test_lattice_modes_keep_the_surviving_fraction(dim, variant, mode, h_ratio):
    """A uniform and a particle-scale (checkerboard) viscous acceleration through the
    correction pass keep, inside the lattice, the fraction ``surviving_fraction`` gives."""
    n = {1: 30, 2: 12, 3: 7}[dim]
    x = lattice(dim, n)
    u = np.zeros_like(x)
    sign = (-1.0) ** np.round(x / DX - 0.5).sum(1) if mode == "2dx" else 1.0
    u[:, 0] = 3.0 * sign
    net, _ = apply_correction(x, u, variant, h_ratio=h_ratio)
    inside = interior(x, dim, n, margin=3)
    expected = surviving_fraction(variant, dim, 1.2, h_ratio, mode) * u[inside, 0]
    np.testing.assert_allclose(net[inside, 0], expected, atol=1e-12)


def test_surviving_fractions_by_hand_1d():
    """1D, h_c = 0.6 dx: the self weight is W(0) dx = 2/(3 * 0.6) = 1.1111; each nearest
    neighbour (q = 1/0.6) adds 2/(3 * 0.6) * (2 - 1/0.6)^3 / 4 = 0.010288."""
    w0 = 2 / (3 * 0.6)
    w1 = w0 * (2 - 1 / 0.6) ** 3 / 4
    assert cubic_spline(0.0, 0.6, 1) == pytest.approx(w0)
    assert surviving_fraction("volume_weighted", 1) == pytest.approx(1 - w0 - 2 * w1)
    assert surviving_fraction("neighbours_only", 1) == pytest.approx(1 - 2 * w1)
    assert surviving_fraction("shepard", 1) == 0.0
    # the 2 dx mode (u_j = -u_i): the nearest neighbours cancel u_i in eq 34's (u_i + u_j)
    assert surviving_fraction("neighbours_only", 1, mode="2dx") == pytest.approx(1.0)
    assert surviving_fraction("volume_weighted", 1, mode="2dx") == pytest.approx(1 - w0)
    assert surviving_fraction("shepard", 1, mode="2dx") == pytest.approx(
        1 - w0 / (w0 + 2 * w1))


@pytest.mark.parametrize("dim", [1, 2])
def test_alternating_field(dim):
    """u = +-U on alternate particles (checkerboard): the nearest neighbours carry -u_i, so
    (a) leaves u_i (1 - w_ii), (b) leaves (u_i - <u>_i)/2 with <u>_i = u_i (w_ii - s)/(w_ii + s),
    (c) leaves u_i untouched (the pair sums u_i + u_j vanish)."""
    n = {1: 30, 2: 12}[dim]
    x = lattice(dim, n)
    idx = np.rint(x / DX - 0.5).astype(int).sum(axis=1)
    u = np.zeros_like(x)
    u[:, 0] = np.where(idx % 2 == 0, 2.0, -2.0)
    inside = interior(x, dim, n)
    w_self = cubic_spline(0.0, 0.6, dim)
    s = 2 * dim * cubic_spline(1.0, 0.6, dim)  # nearest neighbours (diagonals are beyond 2 h_c)
    ui = u[inside, 0]
    net, _ = apply_correction(x, u, "volume_weighted")
    np.testing.assert_allclose(net[inside, 0], ui * (1 - w_self), rtol=1e-12)
    net, _ = apply_correction(x, u, "shepard")
    mean = ui * (w_self - s) / (w_self + s)
    np.testing.assert_allclose(net[inside, 0], 0.5 * (ui - mean), rtol=1e-12)
    net, _ = apply_correction(x, u, "neighbours_only")
    np.testing.assert_allclose(net[inside, 0], ui, rtol=1e-12)


def test_energy_terms():
    """'work' books v_i . u_corr_i; 'paper' is 1/2 sum_j w_ij v_ij . u_j; 'none' is zero."""
    x = lattice(1, 20)
    rng = np.random.default_rng(3)
    u = rng.normal(size=x.shape)
    v = rng.normal(size=x.shape)
    net, de = apply_correction(x, u, "volume_weighted", v=v, energy="work")
    np.testing.assert_allclose(de, np.sum(v * (u - net), axis=1), rtol=1e-12)
    _, de = apply_correction(x, u, "volume_weighted", v=v, energy="paper")
    i = 10
    w1 = cubic_spline(DX, 0.6 * DX, 1) * DX
    by_hand = 0.5 * w1 * ((v[i, 0] - v[i - 1, 0]) * u[i - 1, 0]
                          + (v[i, 0] - v[i + 1, 0]) * u[i + 1, 0])
    assert de[i] == pytest.approx(by_hand, rel=1e-12)
    _, de = apply_correction(x, u, "volume_weighted", v=v, energy="none")
    assert np.all(de == 0)


def test_av_budget_closes(run_bars):
    """With AV the viscosity's heating is the kinetic energy lost (up to the elastic energy
    left ringing in the free bars) and nothing else enters the budget."""
    _, s = run_bars("viscosity.alpha1=0.3", "viscosity.alpha2=0.3")
    lost = s["kinetic_energy_initial"] - s["kinetic_energy_final"]
    assert s["viscous_dissipation"] == pytest.approx(lost, rel=0.1)
    assert s["viscous_dissipation"] <= s["internal_energy_final"] * 1.001
    assert s["correction_work"] == 0.0 and s["correction_heating"] == 0.0
    assert s["energy_imbalance"] == 0.0
    assert s["energy_budget_residual"] == pytest.approx(s["total_energy_relative_error"])


def test_ac_work_variant_conserves_energy_and_books_the_correction(run_bars):
    _, s = run_bars("viscosity.scheme=ac", "viscosity.correction=neighbours_only",
                    "viscosity.energy_correction=work")
    assert s["correction_work"] != 0.0
    assert s["correction_heating"] == pytest.approx(-s["correction_work"], rel=1e-10)
    assert s["total_energy_relative_error"] < 1e-3
    assert s["energy_budget_residual"] < 1e-3
    assert np.isfinite(s["momentum_drift"])


def test_ac_paper_energy_shows_its_imbalance(run_bars):
    """eq 37 does not book the correction's work: the total energy drifts by what the budget
    reports as imbalance, and the budget still closes."""
    _, s = run_bars("viscosity.scheme=ac", "viscosity.correction=neighbours_only",
                    "viscosity.energy_correction=paper")
    assert abs(s["energy_imbalance"]) > 1e-3
    assert s["energy_budget_residual"] < 1e-3
    sim, _ = run_bars("viscosity.scheme=ac", "viscosity.correction=neighbours_only",
                      "viscosity.energy_correction=paper")
    row = sim.record.history[-1]
    e0 = s["kinetic_energy_initial"]
    assert (row["total_energy"] - e0) / e0 == pytest.approx(s["energy_imbalance"], abs=1e-3)


def test_ac_momentum_drift_is_measured_not_hidden():
    """In 2D with random velocities the correction is not antisymmetric: the summary's drift
    is the true change of total momentum, and it is far above AV's round-off.  (AV's drift is
    round-off in both measures, whose sums run in different orders: the survey's chunks and
    ``ParticleState.momentum``'s product; there the two are only held below 1e-13.)"""
    from impactsph.loading import validate_case
    from impactsph.problem import build_problem
    from impactsph.simulation import Simulation

    drift = {}
    for scheme in ("av", "ac"):
        case = validate_case({
            "name": "blob", "dimension": 2,
            "materials": {"m": {"model": "elastic", "density": 7800.0,
                                "youngs_modulus": 2e11}},
            "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0],
                        "geometry": {"origin": [0, 0], "size": [0.012, 0.008],
                                     "spacing": 0.001}}],
            "viscosity": {"scheme": scheme, "correction": "volume_weighted"},
            "time": {"end": 1.0, "max_steps": 40}, "output": {"figures": False},
        })
        problem = build_problem(case)
        rng = np.random.default_rng(7)
        problem.state.velocity[:] = rng.normal(scale=5.0, size=problem.state.velocity.shape)
        p0 = problem.state.momentum()
        scale = np.sum(problem.state.mass * np.linalg.norm(problem.state.velocity, axis=1))
        sim = Simulation(case, problem)
        sim.run()
        true_drift = np.linalg.norm(sim.state.momentum() - p0) / scale
        summary_drift = sim.summary()["momentum_drift"]
        if scheme == "ac":  # the run's largest drift: at least the final one
            assert summary_drift >= true_drift * (1 - 1e-9)
        else:
            assert summary_drift < 1e-13
        drift[scheme] = true_drift
    assert drift["av"] < 1e-13
    assert drift["ac"] > 1e-8


def test_the_inner_list_changes_no_bit(monkeypatch):
    """The correction pass reads the neighbour list's inner list (pairs within h_c's support
    plus the skin: each row's first entries), and so does the pairwise AC's switch pass: the
    paper's Taylor bar (a wall, plasticity; the list rebuilt several times) ends on the same
    bits as with the whole rows, with AC at ``h_c = h/2`` and ``0.3 h`` and with the pairwise
    AC; with ``h_c = h`` the list has no inner part."""
    from impactsph import load_case
    from impactsph.simulation import Simulation

    def final(overrides, whole_list, pass_name):
        with monkeypatch.context() as patch:
            if whole_list:
                patch.setattr(NeighbourList, "within", lambda self, reach: self.offsets[1:])
            sim = Simulation(load_case("taylor", ["time.end=3e-6", *overrides]))
            backend = sim.solver.backend
            read = []  # the rows' ends the pass was given: the inner list's (True) or theirs
            # (the switch pass takes the chunks' first and step before its arguments)
            skip = 2 if pass_name == "switch_pass" else 0
            if pass_name == "switch_pass":  # a module of the scheme's switch alone
                of_kind = backend.switch_pass
                run = lambda *args: of_kind(args[8])(*args)  # noqa: E731 (args[8]: the kind)
            else:
                run = getattr(backend.passes, pass_name)

            def counted(*args):
                nl = sim.solver.neighbours
                assert args[skip + 3] is nl.offsets and args[skip + 5] is nl.indices
                read.append(args[skip + 4] is nl.inner_ends is not None)
                assert read[-1] or np.array_equal(args[skip + 4], nl.offsets[1:])
                return run(*args)

            if pass_name == "switch_pass":
                patch.setattr(backend, "switch_pass", lambda kind: counted)
            else:
                patch.setattr(backend.passes, pass_name, counted)
            sim.run()
        nl = sim.solver.neighbours
        assert nl.builds > 2
        assert set(read) == {nl.inner_ends is not None and not whole_list}
        return sim.state.arrays(), nl

    for overrides, reach, pass_name in (
            ([], 0.5, "correction_pass"),
            (["viscosity.correction_h_ratio=0.3"], 0.3, "correction_pass"),
            (['viscosity.scheme="ac_pairwise"'], 0.5, "switch_pass")):
        inner, nl = final(overrides, False, pass_name)
        whole, _ = final(overrides, True, pass_name)
        assert nl.inner_reach == reach
        # what the pass is spared
        assert (nl.inner_ends - nl.offsets[:-1]).sum() < 0.5 * nl.indices.size
        for name, arr in whole.items():
            np.testing.assert_array_equal(inner[name], arr, err_msg=name)
    _, nl = final(["viscosity.correction_h_ratio=1.0"], False, "correction_pass")
    assert nl.inner_ends is None and nl.inner_reach == 1.0


@pytest.mark.parametrize("energy", ["paper", "work"])
def test_the_books_take_the_power_and_heating_of_what_the_correction_adds(monkeypatch,
                                                                         energy):
    """The run's book of the correction's work rate (``Solver.powers[1]``) is ``sum_i m_i v_i
    . a_c,i`` of the accelerations ``a_c`` the correction adds to the particles, and its
    heating book (``powers[2]``) ``sum_i m_i de_c,i`` of what it adds to their energy rates
    (each particle's two numbers, ``RateBuffers.correction_books``): measured as the change
    of the accelerations and energy rates when the correction pass is left out, on the
    paper's Taylor bar after 2 us (a wall, plasticity), for the paper's energy term and for
    the work's."""
    from impactsph import load_case
    from impactsph.simulation import Simulation

    sim = Simulation(load_case("taylor", ["time.end=2e-6",
                                          f'viscosity.energy_correction="{energy}"']))
    sim.run()
    solver, state = sim.solver, sim.state
    n = solver.n_active
    solver.rates(state)
    dv, de = solver.buffers.dv[:n].copy(), solver.buffers.de[:n].copy()
    power, heating = solver.powers[1], solver.powers[2]
    monkeypatch.setattr(solver.backend.passes, "correction_pass", lambda *args: None)
    solver.rates(state)
    added, added_heat = dv - solver.buffers.dv[:n], de - solver.buffers.de[:n]
    assert np.abs(added).max() > 0.0 and abs(power) > 0.0
    expected = float(np.sum(state.mass[:, None] * state.velocity * added))
    assert power == pytest.approx(expected, rel=1e-9)
    assert heating == pytest.approx(float(np.sum(state.mass * added_heat)), rel=1e-9)
    if energy == "work":  # the work variant heats by what the force works
        assert heating == pytest.approx(-power, rel=1e-12)
