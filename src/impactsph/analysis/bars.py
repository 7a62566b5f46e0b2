"""Example 1: two identical elastic bars in collinear impact, and 1D elastic bar theory.

The left bar occupies ``[-L, 0]`` and moves at ``+V``; the right bar mirrors it.  Elastic
waves travel at ``c = sqrt(E/rho)``.  For a particle of the left bar at initial coordinate
``X``::

    0      < t < L/c  :  v = +V ahead of the compression front X = -c t, 0 behind it
    L/c    < t < 2L/c :  v = 0 ahead of the unloading front X = -L + c (t - L/c), -V behind
    t > 2L/c          :  v = -V (the bars have separated, unstressed, with all their KE)

so the contact time is ``t_c = 2L/c`` and at ``3 t_c / 4`` the free half of the bar moves at
``-V`` while the half at the contact face is at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Time of the paper's velocity profiles (Figs 3-5, 7), s.
PROFILE_TIME = 5.75e-6
#: Window of the mid-bar velocity comparison, s.
MID_WINDOW = 15e-6


@dataclass(frozen=True)
class BarTheory:
    """1D elastic bar theory for the left bar."""

    length: float  #: m
    speed: float  #: m/s, impact speed V of each bar in the centre-of-mass frame
    wave_speed: float  #: m/s, sqrt(E/rho)
    frame_velocity: float = 0.0  #: m/s, velocity U of the centre of mass

    @property
    def contact_time(self) -> float:
        """``t_c = 2 L / c`` (s)."""
        return 2.0 * self.length / self.wave_speed

    def velocity(self, X: np.ndarray, t: float) -> np.ndarray:
        """Velocity of left-bar material points at initial coordinates ``X`` (in [-L, 0])."""
        return self.frame_velocity + self._relative_velocity(np.asarray(X, np.float64), t)

    def _relative_velocity(self, X: np.ndarray, t: float) -> np.ndarray:
        L, c, V = self.length, self.wave_speed, self.speed
        if t <= 0:
            return np.full_like(X, V)
        if t <= L / c:
            return np.where(X < -c * t, V, 0.0)
        if t <= 2 * L / c:
            return np.where(X < -L + c * (t - L / c), -V, 0.0)
        return np.full_like(X, -V)


def theory_for(case: Any) -> BarTheory:
    """Theory matching a bars case: the represented length of the left bar (its particle
    count times the spacing), half the approach speed, the bar-wave speed and the velocity of
    the centre of mass (the theory is Galilean invariant, so is the comparison)."""
    left, right = case.bodies[0], case.bodies[1]
    mat = case.materials[left.material]
    return BarTheory(length=left.geometry.size[0],
                     speed=0.5 * (left.velocity[0] - right.velocity[0]),
                     wave_speed=math.sqrt(mat.youngs_modulus / mat.density),
                     frame_velocity=0.5 * (left.velocity[0] + right.velocity[0]))


def profile_metrics(X: np.ndarray, v: np.ndarray, theory: BarTheory, t: float
                    ) -> dict[str, float]:
    """Relative L1 error of a velocity profile against theory, over the initial coordinate,
    and its total variation in excess of theory's, over ``V``."""
    order = np.argsort(X)
    X, v = X[order], v[order]
    vt = theory.velocity(X, t)
    rel = vt - theory.frame_velocity
    l1 = float(np.sum(np.abs(v - vt)) / np.sum(np.abs(rel))) if np.any(rel) else float("nan")
    tv_num = float(np.sum(np.abs(np.diff(v))))
    tv_theory = float(np.sum(np.abs(np.diff(vt))))
    return {"velocity_profile_l1_error": l1,
            "velocity_profile_oscillation": (tv_num - tv_theory) / theory.speed}


def contact_time(times: np.ndarray, force: np.ndarray, threshold: float = 1e-2) -> float:
    """Duration of the contact: from the first time the contact force exceeds ``threshold``
    times its peak to the first time after that it falls back below it."""
    f = np.abs(force)
    peak = f.max()
    if peak == 0:
        return 0.0
    on = np.flatnonzero(f > threshold * peak)
    start = on[0]
    off = np.flatnonzero(f[start:] <= threshold * peak)
    if off.size == 0:
        return float("nan")
    return float(times[start + off[0]] - times[start])


def bars_metrics(sim: Any) -> dict[str, Any]:
    """Example 1's comparison with theory (see the module docstring)."""
    theory = theory_for(sim.case)
    left_name = sim.problem.body_names[0]
    out: dict[str, Any] = {"contact_time_theory_us": theory.contact_time * 1e6,
                           "bar_length_represented": theory.length}
    hist = sim.record.history
    times = np.array([r["time"] for r in hist])
    force = np.array([r[f"contact_force_{left_name}_x"] for r in hist])
    tc = contact_time(times, force)
    out["contact_time_us"] = tc * 1e6
    snaps = [s for s in sim.record.snapshots if abs(s.time - PROFILE_TIME) < 1e-12]
    if snaps:
        snap = snaps[0]
        left = np.flatnonzero(snap.fields["body"] == 0)
        X = sim.state.initial_position[left, 0]
        out.update(profile_metrics(X, snap.fields["velocity"][left, 0], theory, PROFILE_TIME))
    probe = sim.record.probes.get("mid_left")
    if probe:
        t = np.array([p[0] for p in probe])
        v = np.array([p[1][0] for p in probe])
        X_mid = sim.state.initial_position[sim.problem.probes["mid_left"], 0]
        keep = t <= MID_WINDOW
        vt = np.array([theory.velocity(np.array([X_mid]), ti)[0] for ti in t[keep]])
        err = np.trapezoid(np.abs(v[keep] - vt), t[keep])
        scale = np.trapezoid(np.abs(vt - theory.frame_velocity), t[keep])
        out["mid_velocity_l1_error"] = float(err / scale)
    s = sim.state
    for b, name in enumerate(sim.problem.body_names):
        members = s.body == b
        out[f"final_velocity_{name}"] = float(
            np.dot(s.mass[members], s.velocity[members, 0]) / s.mass[members].sum())
    out["separation_speed_ratio"] = float(
        np.mean([abs(out[f"final_velocity_{n}"] - theory.frame_velocity)
                 for n in sim.problem.body_names]) / theory.speed)
    return out
