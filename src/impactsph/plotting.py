"""Figures (matplotlib, non-interactive backend).  Each function takes one or more runs'
outputs and writes a PNG; :func:`figures_for` draws a finished run's set."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .analysis.bars import MID_WINDOW, PROFILE_TIME, BarTheory  # noqa: E402


def _save(fig, path: Path) -> Path:
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=120, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


ENERGY_UNITS = {1: "J/m^2, per unit cross-section", 2: "J/m, per unit depth", 3: "J"}


def kinetic_energy_figure(runs: list[dict[str, Any]], path: Path, title: str = "",
                          dimension: int | None = 3) -> Path:
    """Kinetic energy against time (paper Figs 6, 9, 12).  ``runs``: dicts with ``label``,
    ``time`` (s) and ``kinetic_energy``; ``dimension`` sets the unit (None: runs of several
    dimensions)."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for r in runs:
        ax.plot(np.asarray(r["time"]) * 1e6, r["kinetic_energy"], label=r["label"])
    ax.set_xlabel("time (us)")
    unit = ENERGY_UNITS.get(dimension, "J, J/m or J/m^2 by dimension")
    ax.set_ylabel(f"kinetic energy ({unit})")
    ax.set_title(title or "Kinetic energy")
    ax.grid(alpha=0.3)
    ax.legend()
    return _save(fig, path)


def bars_profile_figure(runs: list[dict[str, Any]], theory: BarTheory, path: Path) -> Path:
    """Left bar's velocity against initial coordinate at 5.75 us with theory (Figs 3-5, 7).
    ``runs``: dicts with ``label``, ``X`` and ``v``."""
    fig, ax = plt.subplots(figsize=(6, 4))
    X = np.linspace(-theory.length, 0, 2001)
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
    return _save(fig, path)


def bars_mid_velocity_figure(runs: list[dict[str, Any]], theory: BarTheory, X_mid: float,
                             path: Path) -> Path:
    """Velocity history of the left bar's mid particle with theory (Fig 8).  ``runs``: dicts
    with ``label``, ``time`` and ``v``."""
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
    return _save(fig, path)


def label_of(case: Any) -> str:
    """Short label of a run's viscosity settings, e.g. ``AV (0.3, 0.3)``, ``AC (shepard)``."""
    v = case.viscosity
    if v.scheme == "ac":
        return f"AC ({v.correction})"
    return f"AV ({v.alpha1:g}, {v.alpha2:g})"


def shapes_figure(runs: list[dict[str, Any]], path: Path, title: str, *,
                  separate: bool = False) -> Path:
    """Deformed particle positions (paper Figs 11, 13, 15-17).  ``runs``: dicts with
    ``label`` and ``x`` (n, 2).  Overlaid, or side by side with ``separate``."""
    n = len(runs)
    if separate:
        fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 4.5), sharey=True, squeeze=False)
        axes = list(axes[0])
    else:
        fig, ax = plt.subplots(figsize=(6, 5))
        axes = [ax] * n
    for k, (ax, r) in enumerate(zip(axes, runs, strict=True)):
        x = np.asarray(r["x"])
        ax.scatter(x[:, 0] * 1e3, x[:, 1] * 1e3, s=3, color=f"C{k}", label=r["label"])
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.grid(alpha=0.3)
        if separate:
            ax.set_title(r["label"], fontsize=9)
    axes[0].set_ylabel("y (mm)")
    if not separate:
        axes[0].legend(markerscale=4)
        axes[0].set_title(title)
    else:
        fig.suptitle(title)
    return _save(fig, path)


def bar_views_figure(runs: list[dict[str, Any]], path: Path, title: str, *, axis: int,
                     wall_level: float, spacing: float) -> Path:
    """A 3D bar standing on a wall along ``axis`` (the Taylor bar as a cylinder), one row per
    run: the mid-plane section (the particles within one ``spacing`` of the plane through the
    axis and the first lateral axis), every particle's distance from the axis against its
    height (an r-z projection), and the footprint seen from below (the particles within one
    spacing of the wall) with the circles of radius ``R0`` and ``Rf`` (dashed, solid).
    ``runs``: dicts with ``label``, ``x`` (n, 3), ``centre`` (the axis's two lateral
    coordinates), ``R0`` and ``Rf`` (m)."""
    lateral = [a for a in range(3) if a != axis]
    names = ["xyz"[a] for a in lateral] + ["xyz"[axis]]
    n = len(runs)
    fig, axes = plt.subplots(n, 3, figsize=(11, 4.6 * n), squeeze=False,
                             gridspec_kw={"width_ratios": [1, 0.6, 1]})
    t = np.linspace(0, 2 * np.pi, 361)
    for k, (row, r) in enumerate(zip(axes, runs, strict=True)):
        x = np.asarray(r["x"])
        a = x[:, lateral[0]] - r["centre"][0]
        b = x[:, lateral[1]] - r["centre"][1]
        z = x[:, axis] - wall_level
        mid = np.abs(b) < spacing
        row[0].scatter(a[mid] * 1e3, z[mid] * 1e3, s=2, color=f"C{k}")
        row[0].set_xlabel(f"{names[0]} (mm)")
        row[0].set_ylabel(f"{names[2]} above the wall (mm)")
        row[0].set_title(f"{r['label']}: section |{names[1]}| < dx", fontsize=9)
        row[1].scatter(np.hypot(a, b) * 1e3, z * 1e3, s=0.5, color=f"C{k}", alpha=0.3)
        row[1].set_xlabel("distance from the axis r (mm)")
        row[1].set_title("r-z projection, every particle", fontsize=9)
        foot = z < spacing
        row[2].scatter(a[foot] * 1e3, b[foot] * 1e3, s=3, color=f"C{k}")
        for radius, style, what in ((r["R0"], "k--", "R0"), (r["Rf"], "k-", "Rf")):
            row[2].plot(radius * 1e3 * np.cos(t), radius * 1e3 * np.sin(t), style, lw=0.8,
                        label=f"{what} = {radius * 1e3:.3g} mm")
        row[2].set_xlabel(f"{names[0]} (mm)")
        row[2].set_ylabel(f"{names[1]} (mm)")
        row[2].set_title(f"footprint: {names[2]} < dx, Rf/R0 = {r['Rf'] / r['R0']:.3f}",
                         fontsize=9)
        row[2].legend(fontsize=8, loc="upper right")
        for ax in row:
            ax.set_aspect("equal")
            ax.grid(alpha=0.3)
        row[1].set_xlim(left=0)
        row[1].sharey(row[0])
    fig.suptitle(title)
    return _save(fig, path)
