"""Command-line interface: ``impactsph run CASE [--set key=value ...] [--out DIR]``."""

from __future__ import annotations

import json
import logging
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from .config import BUILTIN_CASES, CaseError, load_case

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="SPH for solids under impact, with the Shaw-Reid acceleration "
                       "correction.")
err = Console(stderr=True)

SUMMARY_KEYS = (
    "n_particles", "n_steps", "t_end", "wall_seconds", "pair_evaluations_per_second",
    "kinetic_energy_ratio_final", "total_energy_relative_error", "momentum_drift",
    "contact_time_us", "contact_time_theory_us", "velocity_profile_l1_error",
    "velocity_profile_oscillation", "mid_velocity_l1_error",
)


def _fail(message: str, code: int = 2) -> None:
    # one line, printed as written: line breaks and control characters (from a key or a path
    # in the input) are escaped, and rich replaces no emoji codes
    message = "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in message)
    err.print(f"error: {message}", markup=False, highlight=False, emoji=False, soft_wrap=True)
    raise typer.Exit(code)


@app.command()
def run(
    case: Annotated[str, typer.Argument(help=f"case file, or a built-in case: "
                                             f"{', '.join(BUILTIN_CASES)}")],
    set_: Annotated[list[str] | None, typer.Option(
        "--set", help="override a field by its dotted path, e.g. viscosity.alpha1=0.3")] = None,
    out: Annotated[Path | None, typer.Option(help="output directory (default runs/NAME)")
                   ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
    restart: Annotated[Path | None, typer.Option(
        help="continue from this checkpoint (written with output.checkpoint_interval)")
                       ] = None,
    device: Annotated[str | None, typer.Option(
        help="cpu or gpu: where the rate passes run (same as --set compute.device=...); "
             "gpu falls back to the CPU, with a warning, where no GPU is present")] = None,
) -> None:
    """Run a case: write history, snapshots, summary and figures into the output directory."""
    from .runner import run_case
    from .simulation import SimulationError

    logging.basicConfig(level=logging.WARNING if quiet else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        c = load_case(case, (set_ or []) + ([f"compute.device={device}"] if device else []))
    except CaseError as exc:
        _fail(str(exc))
    out = out or Path("runs") / c.name
    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                        TextColumn("t = {task.fields[t]:.3e} s  step {task.fields[step]}  "
                                   "dt = {task.fields[dt]:.2e} s"),
                        TimeRemainingColumn(), console=err, disable=quiet, transient=True)
    with progress:
        task = progress.add_task(c.name, total=c.time.end, t=0.0, step=0, dt=0.0)

        def update(sim) -> None:
            if sim.state.step % 20 == 0:
                row = sim.record.history[-1]
                progress.update(task, completed=sim.state.time, t=sim.state.time,
                                step=sim.state.step, dt=row["dt"])

        try:
            summary = run_case(c, out, callback=update, restart=restart)
        except SimulationError as exc:
            progress.stop()
            _fail(f"run stopped: {exc}; outputs so far are in {out}", code=3)
        except CaseError as exc:  # found while setting up, e.g. an empty tip-mass region
            progress.stop()
            _fail(str(exc))
    shown = {k: summary[k] for k in SUMMARY_KEYS if k in summary}
    typer.echo(json.dumps(shown, indent=2))
    typer.echo(f"summary: {out / 'summary.json'}")
    for fig in summary.get("figures", []):
        typer.echo(f"figure: {fig}")


@app.command()
def check(case: Annotated[str, typer.Argument(help="case file or built-in name")],
          set_: Annotated[list[str] | None, typer.Option("--set")] = None) -> None:
    """Validate a case without running it."""
    try:
        c = load_case(case, set_ or [])
    except CaseError as exc:
        _fail(str(exc))
    typer.echo(f"{c.name}: valid ({c.dimension}D, {len(c.bodies)} bodies)")


@app.command()
def sweep(
    case: Annotated[str, typer.Argument(help="case file or built-in name")],
    grid: Annotated[list[str], typer.Option(
        help="KEY=V1,V2,... (several: Cartesian product; KEY1,KEY2=... ties keys)")],
    out: Annotated[Path | None, typer.Option(help="output directory (default runs/NAME-sweep)")
                   ] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="fixed override")] = None,
    scheduler: Annotated[str | None, typer.Option(
        help="address of an existing Dask scheduler (default: a local cluster)")] = None,
    workers: Annotated[int | None, typer.Option(help="local workers (default: cores)")] = None,
    threshold: Annotated[float, typer.Option(
        help="oscillation criterion: excess total variation / V below this")] = 0.5,
) -> None:
    """Run a case over a grid of parameters in parallel (Dask); write sweep.csv, sweep.json
    and sweep.png, and name the smallest oscillation-free value of the first parameter."""
    from .sweep import sweep as run_sweep

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        c = load_case(case, set_ or [])
        result = run_sweep(case, grid, out or Path("runs") / f"{c.name}-sweep",
                           scheduler=scheduler, workers=workers, overrides=set_ or [],
                           threshold=threshold)
    except CaseError as exc:
        _fail(str(exc))
    cols = [*result["columns"], "status", "kinetic_energy_ratio_final",
            "velocity_profile_l1_error", "velocity_profile_oscillation"]
    typer.echo("  ".join(cols))
    for row in result["rows"]:
        typer.echo("  ".join(_fmt(row.get(k)) for k in cols))
    f = result["finding"]
    typer.echo(f"smallest oscillation-free {f['parameter']}: {f['smallest_oscillation_free']} "
               f"({f['criterion']})")


@app.command()
def paper(
    case: Annotated[str, typer.Argument(help="the bars case (built-in 'bars' or a file)")
                    ] = "bars",
    out: Annotated[Path, typer.Option(help="output directory")] = Path("runs/paper-bars"),
    workers: Annotated[int | None, typer.Option(help="local workers (default: cores)")] = None,
    scheduler: Annotated[str | None, typer.Option(help="existing Dask scheduler")] = None,
) -> None:
    """Regenerate the paper's Figs 3-9 for the bars, AC overlaid, and the AV/AC table."""
    from .paper import paper_figures

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        result = paper_figures(case, out, workers=workers, scheduler=scheduler)
    except (CaseError, ValueError) as exc:
        _fail(str(exc))
    typer.echo((out / "table.md").read_text())
    for fig in result["figures"]:
        typer.echo(f"figure: {fig}")


def _load_run_dir(path: Path) -> dict:
    """A run directory's outputs (:func:`~impactsph.output.load_run`), its case validated;
    refuses (exit code 2) a directory that is not one."""
    import zipfile

    from .config import validate_case
    from .output import load_run

    missing = [f for f in ("case.json", "history.csv") if not (path / f).is_file()]
    if not path.is_dir() or missing:
        _fail(f"{path} is not a run directory (written by impactsph run): "
              f"{'it does not exist' if not path.exists() else 'no ' + ', '.join(missing)}")
    try:
        loaded = load_run(path)
        validate_case(loaded["case"])
        if "kinetic_energy" not in loaded["history"]:
            raise ValueError("history.csv has no kinetic_energy rows")
    except CaseError as exc:
        _fail(f"{path / 'case.json'}: {exc}")
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        _fail(f"{path}: cannot read the run: {exc}")
    return loaded


@app.command()
def plot(
    run_dir: Annotated[Path, typer.Argument(help="a run directory (written by impactsph run)")],
    out: Annotated[Path | None, typer.Option(help="where to write (default: RUN_DIR)")] = None,
) -> None:
    """Redraw a run's figures from its output files (with its reference run, if it has one)."""
    from .figures import draw_figures

    runs = [_load_run_dir(run_dir)]
    if (run_dir / "reference" / "case.json").is_file():
        runs.append(_load_run_dir(run_dir / "reference"))
    out = out or run_dir
    out.mkdir(parents=True, exist_ok=True)
    for fig in draw_figures(runs, out):
        typer.echo(f"figure: {fig}")


@app.command()
def compare(
    run_dirs: Annotated[list[Path], typer.Argument(help="run directories to overlay")],
    out: Annotated[Path, typer.Option(help="where to write")] = Path("runs/compare"),
    labels: Annotated[str | None, typer.Option(
        help="comma-separated legend labels, one per run (default: the directories' names)")
                      ] = None,
) -> None:
    """Overlay the figures of several runs.

    The kinetic energy always; for runs of the same case also the case's figures (the bars:
    velocity profile and mid-bar velocity with theory; Taylor bar and cantilever: deformed
    shapes)."""
    from .config import validate_case
    from .figures import case_mismatch, draw_figures

    if labels is not None:
        names = [lab.strip() for lab in labels.split(",")]
        if len(names) != len(run_dirs):
            _fail(f"--labels gives {len(names)} labels for {len(run_dirs)} runs")
    else:
        names = [d.name or str(d) for d in run_dirs]
        if len(set(names)) != len(names):
            names = [str(d) for d in run_dirs]
    runs = [_load_run_dir(d) for d in run_dirs]
    mismatch = case_mismatch([validate_case(r["case"]) for r in runs])
    if mismatch is not None:
        typer.echo(f"note: {mismatch}; only the kinetic energy is overlaid", err=True)
    out.mkdir(parents=True, exist_ok=True)
    for fig in draw_figures(runs, out, names):
        typer.echo(f"figure: {fig}")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)[:40]


def main() -> None:  # pragma: no cover
    """Entry point for ``python -m impactsph``."""
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
