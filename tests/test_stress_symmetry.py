"""The deviatoric stress is symmetric to the bit: its rate is written as six components
(:func:`impactsph.physics.stress_rate.jaumann_stress_rate`), the integrator keeps the step's
start as six components and writes ``S_ba = S_ab``.  In 3D the nine-component rate's ``xy`` and
``yx`` were the same sums in different orders, so the deviator drifted from symmetry at
round-off; 1D and 2D runs are unchanged by the six components (their rate was symmetric to
the bit already: the pinned results of ``tests/test_pinned_results.py`` hold)."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.physics.stress_rate import (
    UPPER,
    jaumann_stress_rate,
    symmetric_full,
    symmetric_upper,
)


def test_the_3d_deviator_stays_symmetric_to_the_bit():
    """The 3D Taylor bar's first 20 steps: with the nine-component rate one particle of
    22,908 (commit f82b777) had ``S_xy != S_yx`` at the end (a rare event: the rate's
    difference is at round-off of its spin terms, which the elastic term and the step's
    ``S0 + dt dS`` mostly absorb)."""
    sim = Simulation(load_case("taylor3d", ["time.max_steps=20", "output.figures=false"]))
    sim.run()
    S = sim.state.deviatoric_stress
    assert np.abs(S[:, 0, 1]).max() > 1e6  # sheared (Pa)
    np.testing.assert_array_equal(S, S.transpose(0, 2, 1))
    # the step's start copy and the rate buffer hold six numbers a particle, not nine
    assert sim.integrator._start.deviatoric_stress.shape == (sim.state.n, 6)
    assert sim.solver.buffers.dS.shape[1:] == (6,)


def test_six_components_round_trip():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(5, 3, 3))
    S = A + A.transpose(0, 2, 1)
    six = symmetric_upper(S)
    assert six.shape == (5, 6)
    np.testing.assert_array_equal(six[:, 1], S[:, 0, 1])  # (xx, xy, xz, yy, yz, zz)
    np.testing.assert_array_equal(six[:, 4], S[:, 1, 2])
    np.testing.assert_array_equal(symmetric_full(six), S)
    assert [UPPER[a][b] for a in range(3) for b in range(3)] == [0, 1, 2, 1, 3, 4, 2, 4, 5]


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_the_rate_is_the_jaumann_rate_in_matrix_form(dim):
    """The six components equal ``2 mu dev(D) + W S - S W`` (eqs 14-16) of a random gradient
    and deviator, to round-off."""
    rng = np.random.default_rng(dim)
    L = rng.normal(size=(dim, dim))
    A = rng.normal(size=(3, 3))
    S = A + A.T
    S -= np.trace(S) / 3.0 * np.eye(3)
    mu = 80e9
    six = np.zeros(6)
    jaumann_stress_rate(L, S, mu, six)
    L3 = np.zeros((3, 3))
    L3[:dim, :dim] = L
    D, W = 0.5 * (L3 + L3.T), 0.5 * (L3 - L3.T)
    want = 2.0 * mu * (D - np.trace(D) / 3.0 * np.eye(3)) + W @ S - S @ W
    np.testing.assert_allclose(symmetric_full(six), want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_rates_with_a_nine_component_stress_rate_are_refused():
    """A rates function of one's own that returns the deviator's rate as ``(n, 3, 3)`` gets a
    one-line error naming the array and the shape needed, not the kernel's typing error."""
    from impactsph.integrate import MidpointIntegrator

    sim = Simulation(load_case("bars", ["output.figures=false"]))
    n = sim.state.n
    nine = (np.zeros((n, 1)), np.zeros(n), np.zeros(n), np.zeros((n, 3, 3)), np.zeros((n, 0)))
    integrator = MidpointIntegrator(lambda s, time=None: nine, sim.problem.table, n, 1)
    with pytest.raises(ValueError, match=r"rates' dS has shape \(\d+, 3, 3\); .* \(n, 6\)"):
        integrator.step(sim.state, 1e-9)
