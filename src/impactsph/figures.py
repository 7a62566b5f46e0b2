"""The figures of a run directory (or of several, overlaid), drawn from its files: the
kinetic energy and the energy budget for every run, then the figures of the case's problem
(:meth:`impactsph.problems.ProblemKind.figures`).  A figure that cannot be drawn is reported
(logged, and in the ``notes`` given) and the others are drawn."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .loading import validate_case
from .plotting import energies_figure, kinetic_energy_figure
from .preflight import label_of
from .problems.registry import get_problem

log = logging.getLogger("impactsph")


def case_mismatch(cases: list[Any]) -> str | None:
    """Why runs of these (validated) cases cannot share the problem's figures: they differ in
    name, analysis or dimension.  None when they can."""
    if len({(c.name, c.analysis, c.dimension) for c in cases}) <= 1:
        return None
    kinds = ", ".join(dict.fromkeys(f"{c.name} ({c.dimension}D, analysis {c.analysis})"
                                    for c in cases))
    return f"the runs are of different cases: {kinds}"


def deformed_shapes(runs: list[dict[str, Any]], labels: list[str]
                    ) -> tuple[list[dict[str, Any]], str]:
    """Deformed shapes to overlay: every run at the latest snapshot time they all have, or,
    when they share none, each at its last (the time then in its label).  Also the title's
    time.  Each shape: ``label``, ``x``, ``x0`` (initial positions) and ``case`` (the run's
    validated case).  :class:`ValueError` where no run has a snapshot, which
    :func:`draw_figures` makes a note (the figure is not left out in silence)."""
    with_snaps = [(lab, r) for lab, r in zip(labels, runs, strict=True) if r["snapshots"]]
    if not with_snaps:
        raise ValueError("deformed_shape.png needs a snapshot, and no run took one "
                         "(output.snapshot_times within the run)")

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


def draw_figures(runs: list[dict[str, Any]], out: Path, labels: list[str] | None = None,
                 notes: list[str] | None = None) -> list[Path]:
    """Draw the figures of the loaded ``runs`` (see :func:`~impactsph.output.load_run`) into
    ``out``; several runs are overlaid.  Runs of different cases (see :func:`case_mismatch`)
    share the kinetic energy and the energies only; runs of one case also get its problem's
    figures.  Returns the files written.  A figure that fails is left out: the failure is
    logged and appended to ``notes`` (``figure NAME: not drawn (Error: message)``)."""
    out = Path(out)
    cases = [validate_case(r["case"]) for r in runs]
    labels = labels or [label_of(c) for c in cases]
    mixed = case_mismatch(cases) is not None
    dims = {c.dimension for c in cases}
    dimension = dims.pop() if len(dims) == 1 else None
    names = ", ".join(dict.fromkeys(c.name for c in cases))
    paths: list[Path] = []
    notes = [] if notes is None else notes

    def draw(what: str, figure: Callable[[], Path | list[Path]]) -> None:
        try:
            drawn = figure()
        except Exception as exc:  # noqa: BLE001 - a figure never stops a finished run
            note = f"figure {what}: not drawn ({type(exc).__name__}: {exc})"
            log.warning("%s", note)
            notes.append(note)
            return
        for path in drawn if isinstance(drawn, list) else [drawn]:
            log.info("figure %s", path)
            paths.append(path)

    draw("kinetic_energy.png", lambda: kinetic_energy_figure(
        [{"label": lab, "time": r["history"]["time"],
          "kinetic_energy": r["history"]["kinetic_energy"]} for lab, r in zip(labels, runs,
                                                                              strict=True)],
        out / "kinetic_energy.png", title="Kinetic energy: " + names, dimension=dimension))
    draw("energies.png", lambda: energies_figure(
        [{"label": f"{c.name}: {lab}", "history": r["history"],
          "bodies": [b.name for b in c.bodies]} for lab, r, c in zip(labels, runs, cases,
                                                                     strict=True)],
        out / "energies.png", dimension=dimension, title="Energies: " + names))
    if mixed:
        return paths
    problem = get_problem(cases[0].analysis)
    draw(f"of analysis {problem.name!r}", lambda: list(problem.figures(runs, labels, out)))
    return paths
