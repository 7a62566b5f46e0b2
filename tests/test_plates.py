"""The plate-impact problem (``analysis = "plates"``, :mod:`impactsph.problems.plates`): its
exact two-wave solution, and the run against it at two resolutions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactsph.loading import load_case
from impactsph.problems.plates import plate_theory
from impactsph.runner import run_case

RHO, E, NU, G, Y = 7850.0, 208e9, 0.3, 80e9, 600e6
K = E / (3 * (1 - 2 * NU))


def test_jump_conditions_hold_and_reduce_to_the_linear_waves():
    """Each wave of the solution satisfies [u] = U [eps] and [sigma] = rho0 U [u] on the
    run's stress path; for a weak impact the speeds tend to the longitudinal and bulk wave
    speeds and the plateau to V minus the Hugoniot elastic limit's particle velocity."""
    th = plate_theory(RHO, K, G, Y, 100.0, 0.01)
    lam_y = Y / (2 * G)
    eps1 = -math.expm1(-lam_y)
    s1, s2 = th.stresses
    assert s1 == pytest.approx(K * math.expm1(lam_y) + 2 * Y / 3, rel=1e-14)
    assert 100.0 - th.plateau_velocity == pytest.approx(th.precursor_speed * eps1, rel=1e-12)
    assert s1 == pytest.approx(RHO * th.precursor_speed * (100.0 - th.plateau_velocity),
                               rel=1e-12)
    lam2 = math.log1p((s2 - 2 * Y / 3) / K)
    eps2 = -math.expm1(-lam2)
    assert th.plateau_velocity == pytest.approx(th.plastic_speed * (eps2 - eps1), rel=1e-10)
    assert s2 - s1 == pytest.approx(RHO * th.plastic_speed * th.plateau_velocity, rel=1e-10)
    weak = plate_theory(RHO, K, G, 1e6, 1.0, 0.01)  # Y and V small: the linear limits
    c_l, c_b = math.sqrt((K + 4 * G / 3) / RHO), math.sqrt(K / RHO)
    assert weak.precursor_speed == pytest.approx(c_l, rel=1e-5)
    assert weak.plastic_speed == pytest.approx(c_b, rel=3e-4)  # a strain of 2e-4
    hel = 1e6 / (2 * G) * (K + 4 * G / 3) / (RHO * c_l)  # particle velocity of the HEL
    assert 1.0 - weak.plateau_velocity == pytest.approx(hel, rel=1e-4)
    elastic = plate_theory(RHO, K, G, Y, 10.0, 0.01)  # below the HEL: one wave
    assert elastic.elastic and elastic.precursor_speed == pytest.approx(c_l, rel=2e-3)
    X = np.linspace(-0.01, 0.0, 11)
    np.testing.assert_array_equal(th.velocity(X, 1e-6) > 99.0, X < -th.precursor_speed * 1e-6)


@pytest.fixture(scope="module")
def plates(tmp_path_factory):
    out = tmp_path_factory.mktemp("plates")
    runs = {}
    for spacing in (1e-4, 5e-5):
        case = load_case("plates", [f"bodies.{b}.geometry.spacing={spacing}" for b in (0, 1)])
        runs[spacing] = run_case(case, out / f"dx{spacing}", figures=spacing == 5e-5)
    return runs, out


def test_plate_impact_converges_towards_the_exact_waves(plates):
    """The built-in case (AV (1, 1), 1D uniaxial strain) at 0.1 and 0.05 mm: the profile's
    L1 error and the precursor's speed error fall with the spacing; the plastic front within
    2% of its speed and the plateau within 5% of V at both; energy and momentum kept; the
    figure drawn."""
    runs, out = plates
    coarse, fine = runs[1e-4], runs[5e-5]
    for s in (coarse, fine):
        assert s["status"] == "finished"
        assert s["total_energy_relative_error"] <= 1e-3 and s["momentum_drift"] <= 1e-12
        assert abs(s["plastic_speed_error"]) <= 0.02
        assert abs(s["plateau_velocity_error"]) <= 0.05
        assert s["profile_time_us"] == pytest.approx(1.2)
    assert fine["velocity_profile_l1_error"] < 0.8 * coarse["velocity_profile_l1_error"]
    assert 0 < fine["precursor_speed_error"] < 0.8 * coarse["precursor_speed_error"]
    assert (out / "dx5e-05" / "velocity_profile.png").exists()


def test_plates_without_a_snapshot_before_the_reflection_say_so(tmp_path):
    s = run_case(load_case("plates", ["output.snapshot_times=[]", "time.end=2e-7"]),
                 tmp_path / "r", figures=False)
    assert "velocity_profile_l1_error" not in s
    assert any("no snapshot between 0 and" in n for n in s["notes"])
