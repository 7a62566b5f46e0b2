"""The figures of a run directory (or of several, overlaid), drawn from its files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .analysis.bars import PROFILE_TIME, theory_for
from .analysis.taylor import bar_axis, bar_wall, cylinder_measures
from .config import validate_case
from .plotting import (
    bar_views_figure,
    bars_mid_velocity_figure,
    bars_profile_figure,
    kinetic_energy_figure,
    label_of,
    shapes_figure,
)


def case_mismatch(cases: list[Any]) -> str | None:
    """Why runs of these (validated) cases cannot share the problem's figures: they differ in
    name, analysis or dimension.  None when they can."""
    if len({(c.name, c.analysis, c.dimension) for c in cases}) <= 1:
        return None
    kinds = ", ".join(dict.fromkeys(f"{c.name} ({c.dimension}D, analysis {c.analysis})"
                                    for c in cases))
    return f"the runs are of different cases: {kinds}"


def _shapes(runs: list[dict[str, Any]], labels: list[str]) -> tuple[list[dict[str, Any]], str]:
    """Deformed shapes to overlay: every run at the latest snapshot time they all have, or,
    when they share none, each at its last (the time then in its label).  Also the title's
    time.  Each shape: ``label``, ``x``, ``x0`` (initial positions) and ``case`` (the run's
    validated case)."""
    with_snaps = [(lab, r) for lab, r in zip(labels, runs, strict=True) if r["snapshots"]]
    if not with_snaps:
        return [], ""

    def shape(label: str, run: dict[str, Any], snap: dict[str, Any]) -> dict[str, Any]:
        return {"label": label, "x": snap["position"], "x0": snap["initial_position"],
                "case": validate_case(run["case"])}

    common = set.intersection(*({s["time"] for s in r["snapshots"]} for _, r in with_snaps))
    if common:
        t = max(common)
        return ([shape(lab, r, next(s for s in r["snapshots"] if s["time"] == t))
                 for lab, r in with_snaps], f"t = {t * 1e6:.4g} us")
    return ([shape(f"{lab} (t = {r['snapshots'][-1]['time'] * 1e6:.4g} us)", r,
                   r["snapshots"][-1]) for lab, r in with_snaps], "last snapshots")


def deformed_shapes_figure(shapes: list[dict[str, Any]], path: Path, title: str, *,
                           separate: bool = False) -> Path:
    """The deformed shapes of :func:`_shapes` (or any dicts with ``label``, ``x``, ``x0`` and
    ``case``): the particles in the plane in 1D and 2D (:func:`~.plotting.shapes_figure`), and
    for a 3D Taylor bar its section, r-z projection and footprint
    (:func:`~.plotting.bar_views_figure`), a row per run."""
    first = shapes[0]["case"]
    if first.dimension != 3 or first.analysis != "taylor":
        return shapes_figure(shapes, path, title, separate=separate)
    views = []
    for s in shapes:
        case = s["case"]
        axis = bar_axis(case)
        x0 = np.asarray(s["x0"])
        m = cylinder_measures(x0, np.asarray(s["x"]), axis, case.bodies[0].geometry.spacings(),
                              bar_wall(case, axis))
        views.append({"label": s["label"], "x": s["x"],
                      "centre": x0[:, [a for a in range(3) if a != axis]].mean(axis=0),
                      "R0": m["initial_radius"], "Rf": m["footprint_radius"]})
    axis = bar_axis(first)
    return bar_views_figure(views, path, title, axis=axis, wall_level=bar_wall(first, axis),
                            spacing=first.bodies[0].geometry.spacings()[axis])


def draw_figures(runs: list[dict[str, Any]], out: Path, labels: list[str] | None = None
                 ) -> list[Path]:
    """Draw the figures of the loaded ``runs`` (see :func:`~impactsph.output.load_run`) into
    ``out``; several runs are overlaid.  Runs of different cases (see :func:`case_mismatch`)
    share the kinetic energy only.  Returns the files written."""
    out = Path(out)
    cases = [validate_case(r["case"]) for r in runs]
    labels = labels or [label_of(c) for c in cases]
    mixed = case_mismatch(cases) is not None
    dims = {c.dimension for c in cases}
    paths = [kinetic_energy_figure(
        [{"label": lab, "time": r["history"]["time"],
          "kinetic_energy": r["history"]["kinetic_energy"]} for lab, r in zip(labels, runs,
                                                                              strict=True)],
        out / "kinetic_energy.png",
        title="Kinetic energy: " + ", ".join(dict.fromkeys(c.name for c in cases)),
        dimension=dims.pop() if len(dims) == 1 else None)]
    if mixed:
        return paths
    if cases[0].analysis in ("taylor", "cantilever"):
        shapes, when = _shapes(runs, labels)
        if shapes:
            paths.append(deformed_shapes_figure(shapes, out / "deformed_shape.png",
                                                f"{cases[0].name}: shape at {when}",
                                                separate=cases[0].analysis == "taylor"))
    if cases[0].analysis == "bars":
        theory = theory_for(cases[0])
        profiles, mids = [], []
        X_mid = None
        for lab, r in zip(labels, runs, strict=True):
            for snap in r["snapshots"]:
                if abs(snap["time"] - PROFILE_TIME) < 1e-12:
                    left = snap["body"] == 0
                    profiles.append({"label": lab, "X": snap["initial_position"][left, 0],
                                     "v": snap["velocity"][left, 0]})
            probe = r.get("summary", {}).get("probes", {}).get("mid_left")
            if "mid_left_vx" in r["probes"] and probe is not None:
                mids.append({"label": lab, "time": r["probes"]["time"],
                             "v": r["probes"]["mid_left_vx"]})
                X_mid = float(probe["initial_position"][0]) if X_mid is None else X_mid
        if profiles:
            paths.append(bars_profile_figure(profiles, theory, out / "velocity_profile.png"))
        if mids:
            paths.append(bars_mid_velocity_figure(mids, theory, X_mid,
                                                  out / "mid_velocity.png"))
    return paths


def draw_overlays(runs: list[tuple[str, dict[str, Any]]], out: Path, name: str,
                  kinds: tuple[str, ...]) -> list[Path]:
    """One figure of the bars overlaying labelled runs: ``kinds`` among ``profile``,
    ``mid_velocity``, ``kinetic_energy``; written as ``out/name.png``."""
    if not runs:
        return []
    out = Path(out)
    case = validate_case(runs[0][1]["case"])
    theory = theory_for(case)
    paths = []
    if "profile" in kinds:
        profiles = []
        for lab, r in runs:
            for snap in r["snapshots"]:
                if abs(snap["time"] - PROFILE_TIME) < 1e-12:
                    left = snap["body"] == 0
                    profiles.append({"label": lab, "X": snap["initial_position"][left, 0],
                                     "v": snap["velocity"][left, 0]})
        paths.append(bars_profile_figure(profiles, theory, out / f"{name}.png"))
    if "mid_velocity" in kinds:
        mids = [{"label": lab, "time": r["probes"]["time"], "v": r["probes"]["mid_left_vx"]}
                for lab, r in runs if "mid_left_vx" in r["probes"]]
        X_mid = float(runs[0][1]["summary"]["probes"]["mid_left"]["initial_position"][0])
        paths.append(bars_mid_velocity_figure(mids, theory, X_mid, out / f"{name}.png"))
    if "kinetic_energy" in kinds:
        paths.append(kinetic_energy_figure(
            [{"label": lab, "time": r["history"]["time"],
              "kinetic_energy": r["history"]["kinetic_energy"]} for lab, r in runs],
            out / f"{name}.png", title="Kinetic energy: bars", dimension=case.dimension))
    return paths
