"""Example 1 (colliding bars) against 1D elastic bar theory, and the paper's Figs 3-6 findings
as numbers."""

from __future__ import annotations

import numpy as np
import pytest

AV03 = ("viscosity.alpha1=0.3", "viscosity.alpha2=0.3")


def test_conservation_with_av03(run_bars):
    _, s = run_bars(*AV03)
    assert s["momentum_drift"] < 1e-12
    assert s["total_energy_relative_error"] < 1e-3


def test_contact_time_and_rebound(run_bars):
    _, s = run_bars(*AV03)
    # 2L/c for the paper's 20 mm bar is 7.67 us; our bars represent 101 dx = 20.2 mm (7.74 us)
    assert s["contact_time_us"] == pytest.approx(7.67, rel=0.03)
    assert s["contact_time_us"] == pytest.approx(s["contact_time_theory_us"], rel=0.03)
    assert s["final_velocity_left"] == pytest.approx(-50.0, rel=0.05)
    assert s["final_velocity_right"] == pytest.approx(50.0, rel=0.05)
    assert s["kinetic_energy_ratio_final"] >= 0.90


def test_velocity_profile_at_5_75_us(run_bars):
    """Stated tolerance: relative L1 error of the left bar's profile below 0.15 (the smeared
    front is ~4 particles wide; measured 0.117), mid-bar history below 0.10 (measured 0.067)."""
    _, s = run_bars(*AV03)
    assert s["velocity_profile_l1_error"] < 0.15
    assert s["mid_velocity_l1_error"] < 0.10


def test_bars_separate_unstressed(run_bars):
    sim, _ = run_bars(*AV03)
    hist = sim.record.history
    t = np.array([r["time"] for r in hist])
    f = np.array([r["contact_force_left_x"] for r in hist])
    after = t > 12e-6
    assert np.all(f[after] == 0.0)  # no tension across the interface, no re-contact
    # both bars moved apart
    x = sim.state.position[:, 0]
    assert x[sim.state.body == 0].max() < x[sim.state.body == 1].min() - 0.0002


def test_kinetic_energy_falls_as_alpha1_grows(run_bars):
    """Paper Fig 6: AV3 (2.5, 2.5) < AV1 (1, 1) ~ AV2 (1, 2) < (0.3, 0.3)."""
    ke = {name: run_bars(f"viscosity.alpha1={a1}", f"viscosity.alpha2={a2}")[1][
        "kinetic_energy_ratio_final"]
        for name, (a1, a2) in {"AV03": (0.3, 0.3), "AV1": (1, 1), "AV2": (1, 2),
                               "AV3": (2.5, 2.5)}.items()}
    assert ke["AV3"] < ke["AV1"] - 0.03
    assert ke["AV1"] < ke["AV03"] - 0.03
    assert ke["AV2"] == pytest.approx(ke["AV1"], abs=0.01)  # alpha2 barely matters
    ladder = [run_bars(f"viscosity.alpha1={a}", f"viscosity.alpha2={a}")[1][
        "kinetic_energy_ratio_final"] for a in (0.1, 0.3, 1.0, 2.5)]
    assert np.all(np.diff(ladder) < 0)


def test_alpha2_alone_leaves_the_profile_oscillating(run_bars):
    """Paper Fig 3: alpha1 = 0 with alpha2 = 0.5-2 does not remove the noise; Fig 4: the
    oscillation decreases as alpha1 grows and is gone for AV1."""
    osc = {a2: run_bars("viscosity.alpha1=0", f"viscosity.alpha2={a2}")[1][
        "velocity_profile_oscillation"] for a2 in (0.5, 1.0, 2.0)}
    osc03 = run_bars(*AV03)[1]["velocity_profile_oscillation"]
    osc_av1 = run_bars("viscosity.alpha1=1", "viscosity.alpha2=1")[1][
        "velocity_profile_oscillation"]
    assert min(osc.values()) > 5.0  # several times V of spurious variation
    assert osc03 < 1.0
    assert osc_av1 < 0.05


def test_galilean_invariance(run_bars):
    """A uniform 30 m/s added to both bars changes no relative result (the CFL step depends
    on |v|, so results agree to the integrator's accuracy, not to round-off)."""
    sim0, s0 = run_bars(*AV03)
    sim1, s1 = run_bars(*AV03, "bodies.0.velocity=[80.0]", "bodies.1.velocity=[-20.0]")
    v0 = sim0.record.snapshots[0].fields["velocity"][:, 0]
    v1 = sim1.record.snapshots[0].fields["velocity"][:, 0] - 30.0
    assert np.max(np.abs(v1 - v0)) < 0.02  # m/s, against jumps of 50 m/s
    for key in ("contact_time_us", "velocity_profile_l1_error", "mid_velocity_l1_error",
                "separation_speed_ratio"):
        assert s1[key] == pytest.approx(s0[key], rel=2e-3), key
    assert s1["momentum_drift"] < 1e-12


def test_translation_invariance(run_bars):
    """The bars moved 1 m along their axis (their meeting point, the mid-bar probe with them)
    give the same measures against theory, which is measured from where the bars meet: the
    profile's and the mid-bar velocity's L1 errors, the contact time and the rebound agree to
    1e-6 (round-off at 1 m; they were NaN while the theory put the meeting point at 0)."""
    _, s0 = run_bars(*AV03)
    _, s1 = run_bars(*AV03, "bodies.0.geometry.origin=[0.9798]",
                     "bodies.1.geometry.origin=[1.0]", "output.probes.0.position=[0.9899]")
    for key in ("contact_time_us", "velocity_profile_l1_error", "mid_velocity_l1_error",
                "velocity_profile_oscillation", "separation_speed_ratio"):
        assert np.isfinite(s1[key]), key
        assert s1[key] == pytest.approx(s0[key], rel=1e-6), key
