"""Records in float32 (``compute.record_precision = "float32"``): the packed records the pair
loops read are float32 (the state, the outputs and the sums stay float64); the bars' answer
against 1D bar theory moves by a small fraction of its error at two resolutions, while the
resolution moves it by a fifth; bad values are refused by name.  The device's records in
float32 are compared with the CPU's in ``tests/test_gpu_step.py`` (``taylor-2d-float32``,
defined in ``tests/test_gpu.py``); the Taylor bar's measures in
``validation/record_precision.py``."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph.loading import load_case
from impactsph.physics.options import PassOptions
from impactsph.problems.registry import analyse
from impactsph.simulation import Simulation


def _bars(spacing: float, precision: str, shift: float = 0.0) -> Simulation:
    overrides = [] if shift == 0.0 else [
        f"bodies.0.geometry.origin=[{-0.0202 + shift!r}]", f"bodies.1.geometry.origin=[{shift!r}]",
        "output.probes=[]"]
    sim = Simulation(load_case("bars", [
        "output.figures=false", 'viscosity.scheme="av"', "viscosity.alpha1=0.3",
        "viscosity.alpha2=0.3", f"bodies.0.geometry.spacing={spacing!r}",
        f"bodies.1.geometry.spacing={spacing!r}",
        f'compute.record_precision="{precision}"', *overrides]))
    sim.run()
    return sim


def _bar_momentum(sim: Simulation) -> float:
    """One bar's momentum at the impact speed (kg m/s per unit area)."""
    return float(sim.state.mass[sim.state.body == 0].sum()) * 50.0


@pytest.fixture(scope="module")
def bars():
    """The paper's bars (AV (0.3, 0.3)) at the paper's spacing and at half of it, with float64
    and float32 records: ``{(spacing, precision): (sim, measures)}``."""
    runs = {}
    for spacing in (2e-4, 1e-4):
        for precision in ("float64", "float32"):
            sim = _bars(spacing, precision)
            runs[spacing, precision] = (sim, analyse("bars", sim))
    return runs


def test_float32_records_are_half_the_records_and_nothing_else(bars):
    """The run's records are float32, with the float64 run's columns and the positions' low
    parts (one a dimension); the state stays float64; the two runs differ (the records were
    rounded) but only at the records' rounding: the final velocities agree to 1e-4 of the
    impact speed."""
    sim64, _ = bars[2e-4, "float64"]
    sim32, _ = bars[2e-4, "float32"]
    packed64, packed32 = sim64.solver.backend._packed, sim32.solver.backend._packed
    assert packed32.dtype == np.float32 and packed64.dtype == np.float64
    assert packed32.shape == (packed64.shape[0], packed64.shape[1] + 1)
    assert packed32.nbytes == packed64.nbytes // 2 + 4 * packed64.shape[0]
    for name, array in sim32.state.arrays().items():
        if array.dtype.kind == "f":
            assert array.dtype == np.float64, name
    v64, v32 = sim64.state.velocity, sim32.state.velocity
    assert not np.array_equal(v64, v32)
    assert np.abs(v64 - v32).max() <= 1e-4 * 50.0


@pytest.mark.parametrize("spacing", [2e-4, 1e-4])
def test_float32_records_keep_the_bars_answer_at_two_resolutions(bars, spacing):
    """Against 1D bar theory, the velocity profile's and the mid-bar velocity's L1 errors and
    the contact time move by less than 1e-4 of themselves with float32 records (measured:
    1e-5 and less), while halving the spacing cuts the errors by a fifth to a third; the two
    bars stay mirror images and their momentum stays zero to round-off, as in float64 (the
    pair pass widens a neighbour's mass and volume before its products with the other record
    values, so that the pair forces stay antisymmetric: a float32 product made them so only
    to 1e-10 of a term, and the momentum drifted to 2e-12 of a bar's, 1.2e-9 at 1 m)."""
    _, m64 = bars[spacing, "float64"]
    sim32, m32 = bars[spacing, "float32"]
    for key in ("velocity_profile_l1_error", "mid_velocity_l1_error", "contact_time_us"):
        assert abs(m32[key] - m64[key]) <= 1e-4 * abs(m64[key]), (key, m64[key], m32[key])
    for precision in ("float64", "float32"):
        coarse, fine = bars[2e-4, precision][1], bars[1e-4, precision][1]
        for key in ("velocity_profile_l1_error", "mid_velocity_l1_error"):
            assert fine[key] < 0.85 * coarse[key], (precision, key, coarse[key], fine[key])
    assert m32["final_velocity_left"] == pytest.approx(-m32["final_velocity_right"], rel=1e-12)
    momentum = [row["momentum_x"] for row in sim32.record.history]
    assert np.abs(momentum).max() <= 1e-14 * _bar_momentum(sim32)


def test_float32_records_lose_nothing_to_the_distance_from_the_origin(bars):
    """The bars moved 1 m from the origin (5,000 spacings) run as at the origin with float32
    records: the records carry each position in two parts added in float64, so the pairs'
    separations are as exact as float64's.  The final velocities agree to 1e-6 of the impact
    speed (measured: 1.1e-7; with the position's rounded part alone, 1.7e-4) and the momentum
    stays zero to round-off."""
    near, _ = bars[2e-4, "float32"]
    far = _bars(2e-4, "float32", shift=1.0)
    assert np.abs(far.state.velocity - near.state.velocity).max() <= 1e-6 * 50.0
    np.testing.assert_allclose(far.state.position - 1.0, near.state.position, rtol=0,
                               atol=1e-6 * 2e-4)
    momentum = [row["momentum_x"] for row in far.record.history]
    assert np.abs(momentum).max() <= 1e-14 * _bar_momentum(far)


def test_a_bad_record_precision_is_refused_by_name():
    """A value other than float64 and float32 is refused before any work, naming the field
    and what is allowed; the pass options refuse it too; float32 records are a module of their
    own (their positions in two parts), float64 the default's."""
    with pytest.raises(Exception) as err:
        load_case("bars", ['compute.record_precision="float16"'])
    text = str(err.value)
    assert "record_precision" in text and "float32" in text and "float16" in text
    with pytest.raises(ValueError, match="record_precision = 'half'"):
        PassOptions(record_precision="half")
    options = PassOptions(record_precision="float32")
    assert options.record_dtype == np.float32
    assert options.compiled() != PassOptions().compiled()
    assert "_f32" in options.tag and PassOptions(parallel=True).tag == ""
    assert "SPLIT_POSITIONS = True" in options.constants(2)
    assert "SPLIT_POSITIONS = False" in PassOptions().constants(2)


@pytest.mark.parametrize("scheme", ["ac", "cullen_dehnen", "ac_optimised"])
def test_the_models_neighbour_loops_read_both_parts_of_a_position(scheme):
    """A correction's and a switch's own neighbour loops (AC's sums, the switches' velocity
    gradient, the optimised correction's total variation) read the positions of float32
    records through :func:`impactsph.physics.records.record_coordinate`, both parts: a
    jittered block 100 m from the origin (where float32 rounds a position by up to 0.8% of
    the spacing) gives the answer at the origin to 1e-8 of the largest value (measured: 9e-11
    and less; with the rounded part alone, 8e-6 for Cullen-Dehnen, 3e-3 for AC and 1e-2 for
    the optimised correction), and at the origin float32 records give float64's to 1e-6
    (measured: 7e-8 and less)."""
    from types import SimpleNamespace

    from impactsph.neighbours import NeighbourList
    from impactsph.physics.rates import correction_only, switch_only

    rng = np.random.default_rng(7)
    dx, h = 1e-3, 1.2e-3
    axis = (np.arange(9) + 0.5) * dx
    x = np.stack(np.meshgrid(axis, axis, indexing="ij"), -1).reshape(-1, 2)
    x += rng.uniform(-0.15 * dx, 0.15 * dx, x.shape)
    n = x.shape[0]
    v = -300.0 * (x - x.mean(0)) + rng.normal(0.0, 2.0, x.shape)
    v[:, 0] += 250.0 * (x[:, 1] - x[:, 1].mean())
    u = rng.normal(0.0, 1e7, (n, 2))
    m, rho = np.full(n, 7800.0 * dx**2), 7800.0 * (1 + 0.01 * rng.random(n))
    c, hs, body = rng.uniform(4000.0, 6000.0, n), np.full(n, h), np.zeros(n, np.int32)
    f_now, kept = rng.uniform(0.2, 1.0, n), rng.normal(0.0, 1e4, n)

    def result(shift: float, precision: str) -> np.ndarray:
        xs = x + shift
        nl = NeighbourList.build(xs, 2 * h)
        if scheme == "ac":
            ac = SimpleNamespace(scheme="ac", epsilon=0.01, correction="neighbours_only",
                                 energy_correction="work", correction_h_ratio=1.0)
            return correction_only(xs, v, m, rho, hs, body, nl, u, ac,
                                   record_precision=precision)[0]
        settings = SimpleNamespace(scheme=scheme, alpha1=1.0, alpha2=2.0, epsilon=0.01,
                                   cd_decay=0.05, correction="neighbours_only",
                                   bound_h_ratio=1.0)
        return switch_only(xs, v, m, rho, hs, body, c, nl, u, settings, f_now, 2e-7, kept,
                           record_precision=precision)

    near64, near32, far32 = result(0.0, "float64"), result(0.0, "float32"), result(100.0,
                                                                                   "float32")
    scale = np.abs(near64).max()
    assert np.abs(near32 - near64).max() <= 1e-6 * scale
    assert np.abs(far32 - near32).max() <= 1e-8 * scale
