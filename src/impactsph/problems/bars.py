"""Example 1: two identical elastic bars in collinear impact, and 1D elastic bar theory.

The paper's section 5.1 (parameters in its Table 2, figures 3-9); the set-up and the bars'
represented length in ``docs/modelling.md`` ("The bars' geometry").

The left bar occupies ``[-L, 0]`` and moves at ``+V``; the right bar mirrors it (bars placed
elsewhere are measured from where they meet, ``BarTheory.interface``).  Elastic waves travel
at ``c = sqrt(E/rho)``.  For a particle of the left bar at initial coordinate ``X``::

    0      < t < L/c  :  v = +V ahead of the compression front X = -c t, 0 behind it
    L/c    < t < 2L/c :  v = 0 ahead of the unloading front X = -L + c (t - L/c), -V behind
    t > 2L/c          :  v = -V (the bars have separated, unstressed, with all their KE)

so the contact time is ``t_c = 2L/c`` and at ``3 t_c / 4`` the free half of the bar moves at
``-V`` while the half at the contact face is at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .base import GeometryNeeds, ProblemKind, SweepCriterion

if TYPE_CHECKING:
    from ..config import Case

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
    #: m, where the bars meet: the left bar's right end at t = 0 (0 in the paper's case)
    interface: float = 0.0

    @property
    def contact_time(self) -> float:
        """``t_c = 2 L / c`` (s)."""
        return 2.0 * self.length / self.wave_speed

    def velocity(self, X: np.ndarray, t: float) -> np.ndarray:
        """Velocity of left-bar material points at initial coordinates ``X`` (in
        ``[interface - L, interface]``)."""
        return self.frame_velocity + self._relative_velocity(
            np.asarray(X, np.float64) - self.interface, t)

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
    count times the spacing), half the approach speed, the bar-wave speed, the velocity of
    the centre of mass and where the bars meet, the left bar's right end (the theory is
    Galilean invariant and invariant under translation, so is the comparison)."""
    left, right = case.bodies[0], case.bodies[1]
    mat = case.materials[left.material]
    return BarTheory(length=left.geometry.size[0],
                     speed=0.5 * (left.velocity[0] - right.velocity[0]),
                     wave_speed=math.sqrt(mat.youngs_modulus / mat.density),
                     frame_velocity=0.5 * (left.velocity[0] + right.velocity[0]),
                     interface=left.geometry.origin[0] + left.geometry.size[0])


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
    """Example 1's comparison with theory (see the module docstring), each measure taken on
    its own: one that cannot be taken is left out with a note (``notes``)."""
    from ..measures import attempt

    theory = theory_for(sim.case)
    left_name = sim.problem.body_names[0]
    notes: list[str] = []
    out: dict[str, Any] = {"contact_time_theory_us": theory.contact_time * 1e6,
                           "bar_length_represented": theory.length}
    hist = sim.record.history
    if theory.speed <= 0:
        notes.append("the bars do not approach each other (impact speed "
                     f"{theory.speed:g} m/s): nothing is compared with theory")

    def contact() -> dict[str, Any]:
        times = np.array([r["time"] for r in hist])
        force = np.array([r[f"contact_force_{left_name}_x"] for r in hist])
        tc = contact_time(times, force)
        if tc == 0.0:
            notes.append("contact_time_us: the bars never touched (no contact force)")
        elif math.isnan(tc):
            notes.append(f"contact_time_us: not measured, the bars are still in contact at "
                         f"the end of the run (t = {times[-1] * 1e6:.4g} us)")
        return {"contact_time_us": tc * 1e6}

    out.update(attempt(notes, "contact_time_us", contact, {}))
    snaps = [s for s in sim.record.snapshots if abs(s.time - PROFILE_TIME) < 1e-12]
    if snaps and theory.speed > 0:

        def profile() -> dict[str, float]:
            snap = snaps[0]
            left = np.flatnonzero(snap.fields["body"] == 0)
            X = sim.state.initial_position[left, 0]
            return profile_metrics(X, snap.fields["velocity"][left, 0], theory, PROFILE_TIME)

        out.update(attempt(notes, "velocity_profile", profile, {}))
    elif not snaps:
        notes.append(f"velocity_profile_l1_error: not measured, no snapshot at "
                     f"t = {PROFILE_TIME * 1e6:g} us (output.snapshot_times)")
    probe = sim.record.probes.get("mid_left")
    if probe and theory.speed > 0:

        def mid() -> dict[str, float]:
            t = np.array([p[0] for p in probe])
            v = np.array([p[1][0] for p in probe])
            X_mid = sim.state.initial_position[sim.problem.probes["mid_left"], 0]
            keep = t <= MID_WINDOW
            vt = np.array([theory.velocity(np.array([X_mid]), ti)[0] for ti in t[keep]])
            err = np.trapezoid(np.abs(v[keep] - vt), t[keep])
            scale = np.trapezoid(np.abs(vt - theory.frame_velocity), t[keep])
            if not scale > 0:
                raise ValueError(f"the run ends before the mid-bar velocity changes "
                                 f"(t = {t[-1] * 1e6:.4g} us)")
            return {"mid_velocity_l1_error": float(err / scale)}

        out.update(attempt(notes, "mid_velocity_l1_error", mid, {}))

    def final() -> dict[str, float]:
        s = sim.state
        res = {}
        for b, name in enumerate(sim.problem.body_names):
            members = s.body == b
            res[f"final_velocity_{name}"] = float(
                np.dot(s.inertial_mass[members], s.velocity[members, 0])
                / s.inertial_mass[members].sum())
        if theory.speed > 0:
            res["separation_speed_ratio"] = float(
                np.mean([abs(res[f"final_velocity_{n}"] - theory.frame_velocity)
                         for n in sim.problem.body_names]) / theory.speed)
        return res

    out.update(attempt(notes, "final velocities", final, {}))
    if notes:
        out["notes"] = notes
    return out


# --- the sweep's criterion -------------------------------------------------------------------

#: Default oscillation criterion: spurious total variation below half the impact speed.
OSCILLATION_THRESHOLD = 0.5

#: The paper's "numerical experiment" (section 5, Figs 3-4): the smallest viscosity whose
#: 5.75 us profile is free of spurious oscillation.
OSCILLATION_CRITERION = SweepCriterion(
    key="velocity_profile_oscillation", threshold=OSCILLATION_THRESHOLD,
    name="oscillation_free",
    description="status ok and velocity_profile_oscillation < {threshold} (spurious total "
                "variation of the 5.75 us profile under {threshold} V)",
    label="profile oscillation (excess total variation / V)")


def oscillation_free(row: dict[str, Any], threshold: float) -> bool:
    """The criterion: a stable run whose velocity profile's total variation exceeds theory's
    by less than ``threshold`` times the impact speed."""
    return OSCILLATION_CRITERION.passes(row, threshold)


# --- figures ---------------------------------------------------------------------------------

def bars_profile_figure(runs: list[dict[str, Any]], theory: BarTheory, path: Path) -> Path:
    """Left bar's velocity against initial coordinate at 5.75 us with theory (Figs 3-5, 7).
    ``runs``: dicts with ``label``, ``X`` and ``v``."""
    from ..plotting import plt, save_figure

    fig, ax = plt.subplots(figsize=(6, 4))
    X = np.linspace(theory.interface - theory.length, theory.interface, 2001)
    ax.plot(X * 1e3, theory.velocity(X, PROFILE_TIME), "k:", lw=2, label="theory")
    for r in runs:
        order = np.argsort(r["X"])
        ax.plot(np.asarray(r["X"])[order] * 1e3, np.asarray(r["v"])[order], ".-", ms=3,
                label=r["label"])
    ax.set_xlabel("initial position X (mm)")
    ax.set_ylabel("particle velocity (m/s)")
    ax.set_title(f"Left bar at t = {PROFILE_TIME * 1e6:.2f} us")
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


def bars_mid_velocity_figure(runs: list[dict[str, Any]], theory: BarTheory, X_mid: float,
                             path: Path) -> Path:
    """Velocity history of the left bar's mid particle with theory (Fig 8).  ``runs``: dicts
    with ``label``, ``time`` and ``v``."""
    from ..plotting import plt, save_figure

    fig, ax = plt.subplots(figsize=(6, 4))
    t_max = max([np.max(r["time"]) for r in runs] + [MID_WINDOW])
    t = np.linspace(0, t_max, 2001)
    ax.plot(t * 1e6, [theory.velocity(np.array([X_mid]), ti)[0] for ti in t], "k:", lw=2,
            label="theory")
    for r in runs:
        ax.plot(np.asarray(r["time"]) * 1e6, r["v"], label=r["label"])
    ax.set_xlabel("time (us)")
    ax.set_ylabel("particle velocity (m/s)")
    ax.set_title("Mid-section of the left bar")
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


def _profiles(runs: list[tuple[str, dict[str, Any]]]) -> list[dict[str, Any]]:
    """The left bar's velocity profiles at :data:`PROFILE_TIME` of labelled loaded runs (those
    with a snapshot then)."""
    profiles = []
    for lab, r in runs:
        for snap in r["snapshots"]:
            if abs(snap["time"] - PROFILE_TIME) < 1e-12:
                left = snap["body"] == 0
                profiles.append({"label": lab, "X": snap["initial_position"][left, 0],
                                 "v": snap["velocity"][left, 0]})
    return profiles


def _mid_velocities(runs: list[tuple[str, dict[str, Any]]]
                    ) -> tuple[list[dict[str, Any]], float | None]:
    """The mid-bar probe's velocity histories of labelled loaded runs (those with the
    ``mid_left`` probe), and the probe's initial coordinate (the first run's)."""
    mids, X_mid = [], None
    for lab, r in runs:
        probe = r.get("summary", {}).get("probes", {}).get("mid_left")
        if "mid_left_vx" in r["probes"] and probe is not None:
            mids.append({"label": lab, "time": r["probes"]["time"],
                         "v": r["probes"]["mid_left_vx"]})
            X_mid = float(probe["initial_position"][0]) if X_mid is None else X_mid
    return mids, X_mid


def draw_overlays(runs: list[tuple[str, dict[str, Any]]], out: Path, name: str,
                  kinds: tuple[str, ...]) -> list[Path]:
    """One figure of the bars overlaying labelled runs: ``kinds`` among ``profile``,
    ``mid_velocity``, ``kinetic_energy``; written as ``out/name.png``."""
    from ..loading import validate_case
    from ..plotting import kinetic_energy_figure

    if not runs:
        return []
    out = Path(out)
    case = validate_case(runs[0][1]["case"])
    theory = theory_for(case)
    paths = []
    if "profile" in kinds:
        paths.append(bars_profile_figure(_profiles(runs), theory, out / f"{name}.png"))
    if "mid_velocity" in kinds:
        mids, X_mid = _mid_velocities(runs)
        if mids:
            paths.append(bars_mid_velocity_figure(mids, theory, X_mid, out / f"{name}.png"))
    if "kinetic_energy" in kinds:
        paths.append(kinetic_energy_figure(
            [{"label": lab, "time": r["history"]["time"],
              "kinetic_energy": r["history"]["kinetic_energy"]} for lab, r in runs],
            out / f"{name}.png", title="Kinetic energy: bars", dimension=case.dimension))
    return paths


# --- the paper's figures and table -----------------------------------------------------------

#: Columns of the bars' paper table, and their headings in ``table.md``.
BARS_KEYS = ["run", "status", "kinetic_energy_ratio_final", "velocity_profile_l1_error",
             "velocity_profile_oscillation", "momentum_drift", "total_energy_relative_error",
             "energy_imbalance", "surviving_fraction_1d"]
BARS_HEAD = ["run", "status", "KE kept", "profile L1", "oscillation", "momentum drift",
             "energy error", "energy imbalance", "1 - sum w (1D)"]


def bars_runs() -> dict[str, list[str]]:
    """Label -> overrides of every run the bars' figures and table need."""
    from ..paper import AV_SETS, ac, av, correction_readings

    runs = {f"AV (0, {a2:g})": av(0.0, a2) for a2 in (0.5, 1.0, 1.5, 2.0)}
    runs |= {f"AV ({a:g}, {a:g})": av(a, a) for a in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)}
    runs |= AV_SETS
    for variant in correction_readings().VARIANTS:
        for energy in ("work", "paper"):
            runs[f"AC {variant} / {energy}"] = ac(variant, energy)
    return runs


def bars_paper(base: dict[str, Any], out: Path, workers: int | None = None,
               scheduler: str | None = None) -> dict[str, Any]:
    """The paper's Figs 3-9 for the bars, AC overlaid, and the AV/AC table (see
    :mod:`impactsph.paper`):

    - ``fig3_alpha2_only.png``: profiles at 5.75 us with alpha1 = 0, alpha2 = 0.5, 1, 1.5, 2;
    - ``fig4_alpha_ladder.png``: profiles with alpha1 = alpha2 = 0.05 ... 0.3;
    - ``fig5_profiles.png`` and ``fig6_kinetic_energy.png``: AV1, AV2, AV3 and AV (0.3, 0.3);
    - ``fig7_profile_ac.png``, ``fig8_mid_velocity_ac.png``, ``fig9_kinetic_energy_ac.png``:
      AC against AV (0.3, 0.3) and theory;
    - ``fig7_profile_ac_variants.png``: every reading of AC (``docs/acceleration-correction.md``).

    AC (the default reading) is overlaid on Figs 3-6 as well.  ``table.csv`` and ``table.md``
    give, for AV (0.3, 0.3), AV1, AV2, AV3 and every AC reading: kinetic energy kept, profile
    L1 error and oscillation, momentum drift, energy error and imbalance, and the surviving
    viscosity fraction."""
    from ..paper import (
        DEFAULT_AC,
        correction_readings,
        load_labelled,
        run_labelled,
        status_of,
        write_results,
    )

    readings = correction_readings()
    runs = bars_runs()
    labels = list(runs)
    by_label = run_labelled(base, runs, out, workers=workers, scheduler=scheduler)
    loaded = load_labelled(out, by_label)
    ac = f"AC {DEFAULT_AC} / work"

    def pick(*names: str) -> list[tuple[str, dict[str, Any]]]:
        return [(n, loaded[n]) for n in names if n in loaded]

    ladder = [f"AV ({a:g}, {a:g})" for a in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)]
    figures = {
        "fig3_alpha2_only": pick(*[f"AV (0, {a:g})" for a in (0.5, 1, 1.5, 2)], ac),
        "fig4_alpha_ladder": pick(*ladder, ac),
        "fig5_profiles": pick("AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)", "AV (0.3, 0.3)",
                              ac),
        "fig7_profile_ac": pick(ac, "AV (0.3, 0.3)"),
        "fig7_profile_ac_variants": pick(*[f"AC {v} / work" for v in readings.VARIANTS],
                                         "AV (0.3, 0.3)"),
    }
    paths = []
    for name, sel in figures.items():
        paths += draw_overlays(sel, out, name, kinds=("profile",))
    paths += draw_overlays(pick("AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)", "AV (0.3, 0.3)",
                                ac), out, "fig6_kinetic_energy", kinds=("kinetic_energy",))
    paths += draw_overlays(pick(ac, "AV (0.3, 0.3)"), out, "fig8_mid_velocity_ac",
                           kinds=("mid_velocity",))
    paths += draw_overlays(pick(ac, "AV (0.3, 0.3)"), out, "fig9_kinetic_energy_ac",
                           kinds=("kinetic_energy",))

    table_labels = ["AV (0.3, 0.3)", "AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)",
                    *[k for k in labels if k.startswith("AC ")]]
    table = []
    for lab in table_labels:
        row = by_label[lab]
        variant = lab.split()[1] if lab.startswith("AC ") else None
        table.append({
            "run": lab, "status": status_of(row),
            "kinetic_energy_ratio_final": row.get("kinetic_energy_ratio_final"),
            "velocity_profile_l1_error": row.get("velocity_profile_l1_error"),
            "velocity_profile_oscillation": row.get("velocity_profile_oscillation"),
            "momentum_drift": row.get("momentum_drift"),
            "total_energy_relative_error": row.get("total_energy_relative_error"),
            "energy_imbalance": row.get("energy_imbalance"),
            "surviving_fraction_1d": readings.surviving_fraction(variant, 1) if variant else None,
            "directory": f"runs/{row['run']}",  # (the run's outputs, under OUT)
        })
    return write_results(out, paths, table, BARS_KEYS, BARS_HEAD)


# --- the problem -----------------------------------------------------------------------------

class BarsProblem(ProblemKind):
    """Example 1 (``analysis = "bars"``): the bars against 1D elastic bar theory."""

    name = "bars"
    title = "Example 1: two elastic bars in collinear impact, against 1D bar theory"
    # the theory is that of the blocks' lengths (docs/modelling.md, "The bars' geometry")
    geometry_needs = GeometryNeeds(bodies=2, types=("block",))
    animation_field = "velocity_x"
    sweep_criterion = OSCILLATION_CRITERION

    def metrics(self, sim: Any) -> dict[str, Any]:
        """:func:`bars_metrics`."""
        return bars_metrics(sim)

    def summary_keys(self, case: Case) -> tuple[str, ...]:
        """Contact time (run and theory), profile error and oscillation, mid-bar error."""
        return ("contact_time_us", "contact_time_theory_us", "velocity_profile_l1_error",
                "velocity_profile_oscillation", "mid_velocity_l1_error")

    def table_keys(self, case: Case) -> tuple[str, ...]:
        """Profile error and oscillation, mid-bar error, contact time."""
        return ("velocity_profile_l1_error", "velocity_profile_oscillation",
                "mid_velocity_l1_error", "contact_time_us")

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """``velocity_profile.png`` (the left bar at 5.75 us, Figs 3-5, 7) and
        ``mid_velocity.png`` (the mid-bar probe, Fig 8), with theory; each drawn when some run
        has its data."""
        from ..loading import validate_case

        out = Path(out)
        labelled = list(zip(labels, runs, strict=True))
        theory = theory_for(validate_case(runs[0]["case"]))
        paths = []
        profiles = _profiles(labelled)
        if profiles:
            paths.append(bars_profile_figure(profiles, theory, out / "velocity_profile.png"))
        mids, X_mid = _mid_velocities(labelled)
        if mids:
            paths.append(bars_mid_velocity_figure(mids, theory, X_mid,
                                                  out / "mid_velocity.png"))
        return paths

    def paper(self, base: dict[str, Any], out: Path, *, workers: int | None = None,
              scheduler: str | None = None) -> dict[str, Any]:
        """:func:`bars_paper`: Figs 3-9 and the AV/AC table."""
        return bars_paper(base, out, workers, scheduler)
