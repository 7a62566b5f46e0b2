"""The caches' hints of the CPU passes (``physics/prefetch.py``): a hint changes no value, and
a run large enough to take them gives the rates that a small run gives its particles."""

from __future__ import annotations

import numba as nb
import numpy as np
from fields import random_deviator

from impactsph.loading import validate_case
from impactsph.physics import passes
from impactsph.physics.prefetch import prefetch_row
from impactsph.simulation import Simulation

DX = 1e-3


@nb.njit
def _hinted_sums(a, b, rows):
    """Sums of ``a`` and ``b`` with hints for every row in ``rows`` (some outside the arrays)."""
    for r in rows:
        prefetch_row(a, r, 2, False)
        prefetch_row(b, r, 1, True)
    return a.sum(), b.sum()


@nb.njit
def _sums(a, b):
    return a.sum(), b.sum()


def test_a_hint_changes_no_value_and_faults_on_no_address():
    rng = np.random.default_rng(3)
    a = rng.random((50, 3, 3))
    b = rng.random((50, 2))[:, ::-1]  # not contiguous: the row's stride is read
    rows = np.array([0, 7, 49, 50, 10**6, -3], dtype=np.int32)  # also beyond either end
    before = (a.copy(), b.copy())
    sa, sb = _hinted_sums(a, b, rows)
    assert (sa, sb) == _sums(a, b)
    assert np.array_equal(a, before[0]) and np.array_equal(b, before[1])


def blocks(rows_y: int) -> Simulation:
    """Two steel blocks 64 spacings wide and ``rows_y`` high, side by side a little closer than
    one spacing and approaching (``test_rates_reference.two_blocks``' case and scheme, AC)."""
    case = validate_case({
        "name": "hints", "dimension": 2,
        "materials": {"steel": {"model": "elastic", "density": 7850.0, "youngs_modulus": 2e11,
                                "poisson_ratio": 0.3, "eos": "mie_gruneisen",
                                "mie_gruneisen": {"sound_speed": 4600.0, "slope": 1.5,
                                                  "gamma": 2.0}}},
        "bodies": [
            {"name": "a", "material": "steel", "velocity": [30.0, 0.0],
             "geometry": {"origin": [0.0, 0.0], "size": [64 * DX, rows_y * DX], "spacing": DX}},
            {"name": "b", "material": "steel", "velocity": [-30.0, 0.0],
             "geometry": {"origin": [64 * DX * 0.97, 0.0], "size": [64 * DX, rows_y * DX],
                          "spacing": DX}},
        ],
        "kernel": {"h_over_dx": 1.3}, "viscosity": {"scheme": "ac"},
        "stabilisation": {"gradient_correction": "none", "hourglass": 0.0},
        "contact": {"traction": "pressure"},
        "time": {"end": 1e-6}, "output": {"figures": False},
    })
    return Simulation(case)


def _keys(sim: Simulation) -> list[tuple[int, int, int]]:
    """Each particle's body and place on its lattice (half spacings, before any perturbation)."""
    s = sim.state
    half = np.rint(s.position / (0.5 * DX)).astype(int)
    return [(int(b), int(x), int(y)) for b, (x, y) in zip(s.body, half, strict=True)]


def test_a_run_that_takes_the_hints_gives_a_small_runs_rates():
    """128 rows high (16,384 particles, at ``PREFETCH_ROWS``: the hints on) against the same
    blocks cut to 24 rows (the hints off), every particle given the same perturbed state: the
    particles at least ten spacings below the cut, whose neighbours' neighbours are the same
    in both, get the same rates to round-off (the sums run in other orders)."""
    large, small = blocks(128), blocks(24)
    assert large.state.n >= passes.PREFETCH_ROWS > small.state.n
    rng = np.random.default_rng(16)
    n = large.state.n
    perturbed = {
        "position": large.state.position + rng.normal(0.0, 0.05 * DX, (n, 2)),
        "velocity": large.state.velocity + rng.normal(0.0, 20.0, (n, 2)),
        "density": large.state.density * (1.0 + rng.normal(0.0, 2e-3, n)),
        "specific_energy": rng.uniform(0.0, 1e3, n),
        "deviatoric_stress": random_deviator(rng, n, 2, 2e8),
        "smoothing_length": large.state.smoothing_length * (1.0 + rng.uniform(-0.05, 0.05, n)),
    }
    where = {key: k for k, key in enumerate(_keys(large))}
    taken = np.array([where[key] for key in _keys(small)])
    for name, values in perturbed.items():
        getattr(large.state, name)[...] = values
        getattr(small.state, name)[...] = values[taken]
    got_large = [np.array(a[:n]) for a in large.solver.rates(large.state)[:4]]
    got_small = [np.array(a[: small.state.n]) for a in small.solver.rates(small.state)[:4]]
    inside = small.state.position[:, 1] < 14 * DX
    assert 1000 < np.count_nonzero(inside) < small.state.n
    for name, g_large, g_small in zip(("dv", "drho", "de", "dS"), got_large, got_small,
                                      strict=True):
        want = g_large[taken][inside]
        scale = np.abs(want).max()
        assert scale > 0, name
        np.testing.assert_allclose(g_small[inside], want, rtol=0, atol=1e-12 * scale,
                                   err_msg=name)
