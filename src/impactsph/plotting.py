"""Figures (matplotlib, non-interactive backend) that any problem can draw: each function
takes one or more runs' outputs and writes a PNG.  The problems' own figures are in their
modules (:mod:`impactsph.problems`), which draw with :data:`plt` and save with
:func:`save_figure`; :func:`impactsph.figures.draw_figures` draws a run's set."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .atomic import atomic_path  # noqa: E402
from .preflight import label_of  # noqa: E402, F401 - a run's label, for the figures' legends


def save_figure(fig: matplotlib.figure.Figure, path: Path) -> Path:
    """Write ``fig`` to ``path`` (a PNG, through a temporary file and a rename, so a reader
    never sees a partial one) and close it; return ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight")
    plt.close(fig)
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
    return save_figure(fig, path)


def energies_figure(runs: list[dict[str, Any]], path: Path, dimension: int | None = 3,
                    title: str = "") -> Path:
    """The energy budget against time, one panel per run (at most :data:`ENERGY_PANELS`):
    kinetic, internal and total energy, and the parts of the internal energy that are plastic
    work and viscous heating, from ``history.csv``; with several bodies, each body's kinetic
    energy (thin lines).  ``runs``: dicts with ``label``, ``history`` (columns as arrays)
    and ``bodies`` (names)."""
    shown = runs[:ENERGY_PANELS]
    n = len(shown)
    fig, axes = plt.subplots(1, n, figsize=(6 * n, 4.2), squeeze=False, sharey=True)
    for ax, r in zip(axes[0], shown, strict=True):
        h = r["history"]
        t = np.asarray(h["time"]) * 1e6
        ax.plot(t, h["kinetic_energy"], color="C0", label="kinetic")
        ax.plot(t, h["internal_energy"], color="C1", label="internal")
        ax.plot(t, h["total_energy"], color="k", label="total (kinetic + internal)")
        if "plastic_work" in h:
            ax.plot(t, h["plastic_work"], color="C3", ls="--", label="plastic work (in internal)")
        if np.any(np.asarray(h.get("viscous_dissipation", [0.0])) != 0.0):
            ax.plot(t, h["viscous_dissipation"], color="C2", ls=":",
                    label="viscous heating (in internal)")
        for k, body in enumerate(r.get("bodies", [])):
            column = f"kinetic_energy_{body}"
            if column in h:
                ax.plot(t, h[column], color=f"C{4 + k % 6}", lw=0.8,
                        label=f"kinetic, {body}")
        ax.set_xlabel("time (us)")
        ax.set_title(r["label"], fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    unit = ENERGY_UNITS.get(dimension, "J, J/m or J/m^2 by dimension")
    axes[0][0].set_ylabel(f"energy ({unit})")
    more = f" (the first {n} of {len(runs)} runs)" if len(runs) > n else ""
    fig.suptitle((title or "Energies") + more)
    return save_figure(fig, path)


#: the most runs :func:`energies_figure` draws, one panel each
ENERGY_PANELS = 4


def shapes_figure(runs: list[dict[str, Any]], path: Path, title: str, *,
                  separate: bool = False) -> Path:
    """Deformed particle positions (paper Figs 11, 13, 15-17).  ``runs``: dicts with
    ``label`` and ``x`` (n, 2).  Overlaid, or side by side with ``separate``."""
    n = len(runs)
    if separate:
        # both axes shared: with equal aspects, each panel then has the same scale (sharing
        # y alone let each panel's width set its own: 12.8 against 14.3 px/mm, 2026-12-08)
        fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 4.5), sharex=True, sharey=True,
                                 squeeze=False)
        axes = list(axes[0])
    else:
        fig, ax = plt.subplots(figsize=(6, 5))
        axes = [ax] * n
    axisymmetric = False
    for k, (ax, r) in enumerate(zip(axes, runs, strict=True)):
        x = np.asarray(r["x"])
        ax.scatter(x[:, 0] * 1e3, x[:, 1] * 1e3, s=3, color=f"C{k}", label=r["label"])
        if getattr(r.get("case"), "two_dimensional", None) == "axisymmetric":
            # the half-section's mirror across the axis, pale: the body's whole section
            axisymmetric = True
            ax.scatter(-x[:, 0] * 1e3, x[:, 1] * 1e3, s=3, color=f"C{k}", alpha=0.25)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        if separate:
            ax.set_title(r["label"], fontsize=9)
    for ax in axes:
        ax.set_xlabel("r (mm)" if axisymmetric else "x (mm)")
    axes[0].set_ylabel("z (mm)" if axisymmetric else "y (mm)")
    if not separate:
        axes[0].legend(markerscale=4)
        axes[0].set_title(title)
    else:
        fig.suptitle(title)
    return save_figure(fig, path)
