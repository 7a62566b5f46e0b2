"""The paper's figures and comparison tables: ``impactsph paper CASE --out DIR``.

:func:`paper_figures` hands the case to its problem's :meth:`~impactsph.problems.ProblemKind.
paper`, which runs every case its figures need (in parallel, through
:func:`~impactsph.sweep.run_many`), then draws them with AC overlaid and writes ``table.csv``,
``table.md`` and ``paper.json``.  The paper's examples (section 5) have one each:

- ``bars`` (Example 1): Figs 3-9 and the AV/AC table (:func:`impactsph.problems.bars.
  bars_paper`);
- ``taylor`` (Example 2): Figs 11-13 (:func:`impactsph.problems.taylor.taylor_paper`);
- ``cantilever`` (Example 3): Figs 15-17 (:func:`impactsph.problems.cantilever.
  cantilever_paper`).

The rest of this module is what those functions share: the paper's viscosity settings as
overrides, running and loading labelled runs, the deformed shapes and kinetic energy of
loaded runs, and the tables.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .config import Case
from .loading import read_case_dict, validate_case
from .output import _csv_text, atomic_write_text, load_run, write_study
from .problems.registry import get_problem, problem_names
from .sweep import run_many


def correction_readings() -> Any:
    """The module of the acceleration correction's readings of eq 34 (``VARIANTS``,
    ``surviving_fraction``; ``docs/acceleration-correction.md``)."""
    from .models.viscosity import correction

    return correction


#: The default reading of AC's eq 34 (``docs/acceleration-correction.md``).
DEFAULT_AC: str = correction_readings().DEFAULT_VARIANT


def av(a1: float, a2: float) -> list[str]:
    """Overrides of artificial viscosity (alpha1, alpha2) (eqs 29-30)."""
    return ["viscosity.scheme=\"av\"", f"viscosity.alpha1={a1}", f"viscosity.alpha2={a2}"]


def ac(variant: str, energy: str = "work") -> list[str]:
    """Overrides of the acceleration correction in the reading ``variant`` of eq 34, with the
    energy term ``energy`` (eq 37)."""
    return ["viscosity.scheme=\"ac\"", f"viscosity.correction=\"{variant}\"",
            f"viscosity.energy_correction=\"{energy}\""]


#: The paper's named viscosity sets AV1, AV2, AV3 (section 5), as overrides.
AV_SETS: dict[str, list[str]] = {"AV1 (1, 1)": av(1, 1), "AV2 (1, 2)": av(1, 2),
                                 "AV3 (2.5, 2.5)": av(2.5, 2.5)}


def paper_problems() -> list[str]:
    """The registered problems that have paper figures."""
    return [n for n in problem_names() if get_problem(n).has_paper]


def paper_figures(case_source: str, out: Path | str, *, workers: int | None = None,
                  scheduler: str | None = None) -> dict[str, Any]:
    """Run and draw the paper's figures and table of the case's example into ``out`` (its
    problem's :meth:`~impactsph.problems.ProblemKind.paper`).  A case whose problem has none
    is refused (:class:`ValueError`) before anything is written."""
    out = Path(out)
    base = read_case_dict(case_source)
    analysis = validate_case(base).analysis
    problem = get_problem(analysis)
    if not problem.has_paper:
        raise ValueError(f"analysis = {analysis!r} has no paper figures; the problems that "
                         f"have: {', '.join(paper_problems())}")
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file, not a directory")
    out.mkdir(parents=True, exist_ok=True)
    return problem.paper(base, out, workers=workers, scheduler=scheduler)


def run_labelled(base: dict[str, Any], runs: dict[str, list[str]], out: Path, *,
                 workers: int | None = None, scheduler: str | None = None
                 ) -> dict[str, dict[str, Any]]:
    """Run the case dict ``base`` once per labelled override list, figures off, into
    ``out/runs/<id>`` (:func:`~impactsph.sweep.run_many`).  Returns label -> the run's table
    row (``run``: its directory's name, ``status`` and the sweep's table columns)."""
    labels = list(runs)
    rows = run_many(base, [[*runs[k], "output.figures=false"] for k in labels], out,
                    workers=workers, scheduler=scheduler)
    return dict(zip(labels, rows, strict=True))


def load_labelled(out: Path, rows: dict[str, dict[str, Any]], *, ok_only: bool = False
                  ) -> dict[str, dict[str, Any]]:
    """Label -> the loaded run (:func:`~impactsph.output.load_run`) of the rows of
    :func:`run_labelled`; with ``ok_only``, of those whose status is ``ok`` only."""
    return {lab: load_run(out / "runs" / row["run"]) for lab, row in rows.items()
            if not ok_only or row.get("status") == "ok"}


def status_of(row: dict[str, Any]) -> str:
    """A run's status without its detail: ``ok``, ``unstable``, ``failed`` (``?``: none)."""
    return row.get("status", "?").split(":")[0]


def final_shapes(loaded: dict[str, dict[str, Any]], labels: list[str]) -> list[dict[str, Any]]:
    """The last snapshot of each labelled loaded run that has one, as the shapes of
    :func:`impactsph.figures.deformed_shapes` (``label``, ``x``, ``x0``, ``case``)."""
    return [{"label": n, "x": loaded[n]["snapshots"][-1]["position"],
             "x0": loaded[n]["snapshots"][-1]["initial_position"],
             "case": validate_case(loaded[n]["case"])}
            for n in labels if n in loaded and loaded[n]["snapshots"]]


def kinetic_energy_overlay(loaded: dict[str, dict[str, Any]], labels: list[str], path: Path,
                           title: str, dimension: int | None) -> Path:
    """The kinetic energy of the labelled loaded runs (those present), overlaid."""
    from .plotting import kinetic_energy_figure

    return kinetic_energy_figure(
        [{"label": n, "time": loaded[n]["history"]["time"],
          "kinetic_energy": loaded[n]["history"]["kinetic_energy"]}
         for n in labels if n in loaded], path, title=title, dimension=dimension)


def measure_keys(case: Case) -> tuple[str, ...]:
    """Columns of a paper table of the problem's measures: the problem's
    (:meth:`~impactsph.problems.ProblemKind.table_keys`), then the kinetic energy kept and the
    conservation errors."""
    return (*get_problem(case.analysis).table_keys(case), "kinetic_energy_ratio_final",
            "total_energy_relative_error", "momentum_drift")


def measures_table(rows: dict[str, dict[str, Any]], loaded: dict[str, dict[str, Any]],
                   keys: tuple[str, ...]) -> list[dict[str, Any]]:
    """One table row per labelled run: ``run`` (the label), ``status``, and ``keys`` from its
    summary (None for a run not loaded)."""
    table = []
    for lab, row in rows.items():
        summary = loaded[lab]["summary"] if lab in loaded else {}
        table.append({"run": lab, "status": status_of(row),
                      **{k: summary.get(k) for k in keys},
                      "directory": f"runs/{row['run']}"})  # (the run's outputs, under OUT)
    return table


def write_results(out: Path, paths: list[Path], table: list[dict[str, Any]],
                  keys: list[str] | None = None, head: list[str] | None = None
                  ) -> dict[str, Any]:
    """Write ``table.csv``, ``table.md`` (:func:`markdown_table` with ``keys`` and ``head``)
    and ``paper.json`` into ``out``; return the result, ``{"figures", "table"}``."""
    atomic_write_text(out / "table.csv", _csv_text(table))
    atomic_write_text(out / "table.md", markdown_table(table, keys, head))
    result = {"figures": [str(p) for p in paths], "table": table}
    write_study(out / "paper.json", result)  # (with the versions and the command)
    return result


def markdown_table(rows: list[dict[str, Any]], keys: list[str] | None = None,
                   head: list[str] | None = None) -> str:
    """A comparison table in Markdown: the columns ``keys`` (default: the first row's keys)
    headed ``head`` (default: the keys)."""
    keys = keys or (list(rows[0]) if rows else [])
    head = head or keys

    def fmt(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) >= 1e-3 or v == 0 else f"{v:.1e}"
        return str(v)

    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(fmt(r.get(k)) for k in keys) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def shapes_paper(base: dict[str, Any], out: Path, runs: dict[str, list[str]],
                 figures: list[tuple[str, list[str], str]], shapes_figure: Any,
                 kinetic_energy: tuple[str, list[str], str], *, workers: int | None = None,
                 scheduler: str | None = None) -> dict[str, Any]:
    """The paper's figures of a problem drawn as deformed shapes (Examples 2 and 3): run the
    labelled ``runs``; draw each of ``figures`` (file name, labels, title) with
    ``shapes_figure(shapes, path, title)`` and the kinetic energy (file name, labels, title);
    write the table of the problem's measures for every run."""
    from .loading import validate_case

    case = validate_case(base)
    by_label = run_labelled(base, runs, out, workers=workers, scheduler=scheduler)
    loaded = load_labelled(out, by_label, ok_only=True)
    paths = []
    for name, names, title in figures:
        shapes = final_shapes(loaded, names)
        if shapes:
            paths.append(shapes_figure(shapes, out / f"{name}.png", title))
    name, names, title = kinetic_energy
    paths.append(kinetic_energy_overlay(loaded, names, out / f"{name}.png", title,
                                        case.dimension))
    keys = measure_keys(case)
    return write_results(out, paths, measures_table(by_label, loaded, keys),
                         ["run", "status", *keys])
