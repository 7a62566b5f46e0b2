"""Command-line interface: ``impactsph run CASE [--set key=value ...] [--out DIR]``."""

from __future__ import annotations

import inspect
import json
import logging
import math
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from .config import CaseError
from .errors import RunInterrupted
from .interrupt import StopRequest
from .lab import LONG as LAB_LONG
from .lab import PROBLEMS as LAB_PROBLEMS
from .loading import BUILTIN_CASES, load_case

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="SPH for solids under impact, with the Shaw-Reid acceleration "
                       "correction.")
err = Console(stderr=True)


def _version(value: bool) -> None:
    if value:
        from ._version import __version__

        typer.echo(f"impactsph {__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: Annotated[bool, typer.Option(
        "--version", callback=_version, is_eager=True,
        help="print the version and exit")] = False) -> None:
    """SPH for solids under impact, with the Shaw-Reid acceleration correction."""
    from .physics.options import parallel_default

    try:  # the environment's settings, before any command does work
        parallel_default()
    except ValueError as exc:
        _fail(str(exc))

#: What ``impactsph run`` prints of every run's summary; the case's problem adds its own
#: (:meth:`impactsph.problems.ProblemKind.summary_keys`).
SUMMARY_KEYS = (
    "n_particles", "n_steps", "t_end", "wall_seconds", "compile_seconds",
    "pair_evaluations_per_second",
    "kinetic_energy_ratio_final", "total_energy_relative_error", "momentum_drift",
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
    out: Annotated[Path | None, typer.Option(
        help="output directory (default runs/NAME); it must be empty or new, unless "
             "--overwrite or --restart")] = None,
    quiet: Annotated[bool, typer.Option(
        "--quiet", "-q", help="no progress bar, and of the log and the checks before the "
        "run the warnings and errors only")] = False,
    restart: Annotated[Path | None, typer.Option(
        help="continue from this checkpoint (DIR/checkpoint.h5, written periodically and "
             "when a run is interrupted); --out may then hold the run already")] = None,
    overwrite: Annotated[bool, typer.Option(
        "--overwrite", help="remove the outputs of a previous run in --out first")] = False,
    device: Annotated[str | None, typer.Option(
        help="cpu or gpu: where the rate passes run (same as --set compute.device=...); "
             "gpu falls back to the CPU, with a warning, where no GPU is present")] = None,
) -> None:
    """Run a case: write history, snapshots, summary and figures into the output directory.

    Ctrl-C or SIGTERM stops the run after its current step with a checkpoint, and prints
    the command that continues it (exit code 130)."""
    from .interrupt import stop_on_signals

    with stop_on_signals() as stop:
        try:
            _run(case, set_ or [], out, quiet, restart, overwrite, device, stop)
        except KeyboardInterrupt:  # before the run was set up: nothing to continue from
            _say("interrupted while setting up the run, before its first step; nothing to "
                 "continue from")
            raise typer.Exit(INTERRUPTED) from None


def _run(case: str, sets: list[str], out: Path | None, quiet: bool, restart: Path | None,
         overwrite: bool, device: str | None, stop: StopRequest) -> None:
    """``impactsph run`` with the signals handled by ``stop``."""
    from .errors import OutputError
    from .preflight import after_run, before_run
    from .runner import check_out, run_case
    from .simulation import SimulationError

    logging.basicConfig(level=logging.WARNING if quiet else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    # the run's own log; other libraries' warnings only (matplotlib's "generated new
    # fontManager" on a fresh machine is not the run's news)
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
    try:
        c = load_case(case, sets + ([f"compute.device={device}"] if device else []))
        out = out or Path("runs") / c.name
        # what is refused without building anything, before the preflight's lines: the
        # output directory and the checkpoint (run_case checks both again)
        check_out(out, "overwrite" if overwrite else "refuse", restart is not None, c)
        start = 0.0
        if restart is not None:
            from .checkpoint import verify_checkpoint  # (h5py: only for a restart)

            start = verify_checkpoint(restart, c)
        before_run(c, quiet=quiet, start=start)  # estimates, warnings; CaseError: a refusal
    except (CaseError, OutputError) as exc:
        _fail(str(exc))
    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                        TextColumn("t = {task.fields[t]:.3e} s  step {task.fields[step]}  "
                                   "dt = {task.fields[dt]:.2e} s"),
                        TimeRemainingColumn(), console=err, disable=quiet, transient=True)
    with progress:
        task = progress.add_task(c.name, total=c.time.end, t=0.0, step=0, dt=0.0)

        def update(sim) -> None:
            if sim.step % 20 == 0:  # sim.time and sim.step: no download of a GPU state
                row = sim.record.history[-1]
                progress.update(task, completed=sim.time, t=sim.time, step=sim.step,
                                dt=row["dt"])

        try:
            summary = run_case(c, out, callback=update, restart=restart, stop=stop,
                               if_exists="overwrite" if overwrite else "refuse")
        except SimulationError as exc:
            progress.stop()
            _fail(f"run stopped: {exc}; outputs so far are in {out}", code=3)
        except CaseError as exc:  # found while setting up, e.g. an empty tip-mass region
            progress.stop()
            _fail(str(exc))
        except RunInterrupted as exc:
            progress.stop()
            _interrupted(exc, case, out, sets, device)
        except KeyboardInterrupt:
            progress.stop()
            if not stop.armed:
                raise
            _stopped_at_once(out)  # a second Ctrl-C while a step was still going
        except OutputError as exc:
            progress.stop()
            _fail(str(exc))
        except OSError as exc:  # any other failure to write an output
            from .atomic import output_error

            progress.stop()
            _fail(str(output_error(exc, exc.filename or out)))
    from .output import json_text
    from .problems.registry import get_problem

    keys = (*SUMMARY_KEYS, *get_problem(c.analysis).summary_keys(c))
    shown = {k: summary[k] for k in keys if k in summary}
    typer.echo(json_text(shown))
    typer.echo(f"summary: {out / 'summary.json'}")
    for fig in summary.get("figures", []):
        typer.echo(f"figure: {fig}")
    typer.echo(f"log: {out / 'run.log'}")
    for note in summary.get("notes", []):
        _say(f"note: {note}")
    after_run(c, summary, restarted=restart is not None)  # e.g. kinetic energy left


#: exit code of a run stopped by Ctrl-C or SIGTERM (128 + SIGINT, as shells report Ctrl-C)
INTERRUPTED = 130


def _study_interrupted(out: Path) -> None:
    """The one line of a sweep, lab or paper stopped by Ctrl-C (exit code 130): what is kept
    and how to go on (it printed Dask's notices only)."""
    _say(f"interrupted: the finished runs are kept in {out}/runs; the same command goes on, "
         f"reusing them and continuing each unfinished run from its checkpoint where it has "
         f"one")
    raise typer.Exit(INTERRUPTED)


def _say(message: str) -> None:
    """One line on stderr, printed as written."""
    message = "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in message)
    err.print(message, markup=False, highlight=False, emoji=False, soft_wrap=True)


def _interrupted(exc: RunInterrupted, case: str, out: Path, sets: list[str],
                 device: str | None) -> None:
    """The one line of a run stopped on request, with the command that continues it."""
    import shlex

    if exc.finished:
        _say(f"{exc}; the outputs of the run are complete in {out} "
             f"(impactsph plot {shlex.quote(str(out))} draws the figures)")
        raise typer.Exit(INTERRUPTED)
    command = ["impactsph", "run", case, "--out", str(out), "--restart", exc.checkpoint]
    for s in sets:
        command += ["--set", s]
    if device:
        command += ["--device", device]
    _say(f"interrupted at t = {exc.time:.6e} s, step {exc.step}: checkpoint, history and "
         f"summary written; continue with: {shlex.join(command)}")
    raise typer.Exit(INTERRUPTED)


def _stopped_at_once(out: Path) -> None:
    checkpoint = out / "checkpoint.h5"
    _say(f"interrupted again: stopped at once, mid-step, without a checkpoint of this step; "
         f"the history so far is in {out / 'history.csv'}"
         + (f", and {checkpoint} (an earlier checkpoint) can be continued from with --restart"
            if checkpoint.is_file() else ""))
    raise typer.Exit(INTERRUPTED)


@app.command()
def check(case: Annotated[str, typer.Argument(help="case file or built-in name")],
          set_: Annotated[list[str] | None, typer.Option(
              "--set", help="override a field by its dotted path, e.g. "
              "viscosity.alpha1=0.3")] = None) -> None:
    """Validate a case without running it: particle counts, estimates of memory and run
    time, and warnings about the set-up (impactsph.preflight)."""
    from .preflight import check_case, scheme_line

    try:
        c = load_case(case, set_ or [])
        report = check_case(c)  # CaseError on a refusal
    except CaseError as exc:
        _fail(str(exc))
    model = f" {c.two_dimensional.replace('_', ' ')}" if c.dimension == 2 else ""
    bodies = f"{len(c.bodies)} bod{'y' if len(c.bodies) == 1 else 'ies'}"
    typer.echo(f"{c.name}: valid ({c.dimension}D{model}, {bodies})")
    typer.echo(scheme_line(c))
    typer.echo("\n".join(report.lines()))


@app.command()
def materials(name: Annotated[str | None, typer.Argument(
        help="a library material: print all its fields and sources as a case table")] = None
              ) -> None:
    """The material library: each material's models and the published source of its
    parameters (use one in a case with [materials.X] library = "NAME")."""
    from .library import INFORMATION, library

    entries = library()
    if name is None:
        for key, entry in entries.items():
            typer.echo(f"{key}: {entry.get('description', '')}")
            typer.echo(f"    eos {entry.get('eos', 'linear')}, model {entry.get('model')}, "
                       f"damage {entry.get('damage', 'none')}")
            for part, source in entry.get("sources", {}).items():
                typer.echo(f"    {part}: {source}")
        return
    if name not in entries:
        _fail(f"materials {name!r}: not a library material; one of "
              f"{', '.join(sorted(entries))}")
    entry = entries[name]
    typer.echo(f"# {name}: {entry.get('description', '')}")
    for part, source in entry.get("sources", {}).items():
        typer.echo(f"# {part}: {source}")
    typer.echo(f"[materials.{name}]")
    tables = {k: v for k, v in entry.items() if isinstance(v, dict) and k not in INFORMATION}
    for key, value in entry.items():
        if key not in INFORMATION and key not in tables:
            typer.echo(f"{key} = {_toml_value(value)}")
    for table, fields in tables.items():
        typer.echo(f"[materials.{name}.{table}]")
        for key, value in fields.items():
            typer.echo(f"{key} = {_toml_value(value)}")


def _toml_value(value) -> str:
    return json.dumps(value) if isinstance(value, str) else repr(value)


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
    threshold: Annotated[float | None, typer.Option(
        help="threshold of the problem's sweep criterion (the bars: oscillation, excess "
             "total variation / V below this, default 0.5); unused by a problem without "
             "one")] = None,
    metric: Annotated[list[str] | None, typer.Option(
        help="a value of the runs' summary.json to tabulate and plot against the grid "
             "(sweep_KEY.png); a dotted path for nested ones, e.g. final_length_ratio, "
             "bodies.bar.max_displacement, gauges.tip.max_displacement; repeatable")] = None,
) -> None:
    """Run a case over a grid of parameters in parallel (Dask); write sweep.csv, sweep.json
    and sweep.png (and sweep_KEY.png per --metric).  Each run writes into
    OUT/runs/NAME, named by its grid values.  For a problem with a sweep criterion (the bars:
    a profile free of spurious oscillation), name the smallest value of the first parameter
    that varies that meets it."""
    from .problems.registry import get_problem
    from .sweep import sweep as run_sweep

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    target = out or Path("runs")  # (its name once the case is read)
    try:
        c = load_case(case, set_ or [])
        target = out or Path("runs") / f"{c.name}-sweep"
        result = run_sweep(case, grid, target, scheduler=scheduler, workers=workers,
                           overrides=set_ or [], threshold=threshold, metrics=metric or [])
    except CaseError as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        _study_interrupted(target)
    problem = get_problem(c.analysis)
    cols = [*result["columns"], "run", "status", "kinetic_energy_ratio_final",
            *problem.table_keys(c), *[m for m in result["metrics"]
                                      if m not in problem.table_keys(c)]]
    typer.echo("  ".join(cols))
    for row in result["rows"]:
        typer.echo("  ".join(_fmt(row.get(k)) for k in cols))
    f, criterion = result["finding"], problem.sweep_criterion
    if f is not None and criterion is not None:
        typer.echo(f"smallest {criterion.name.replace('_', '-')} {f['parameter']}: "
                   f"{f[f'smallest_{criterion.name}']} ({f['criterion']})")
    for fig in result["figures"]:
        typer.echo(f"figure: {fig}")
    for note in result["notes"]:
        _say(f"note: {note}")


@app.command()
def lab(
    out: Annotated[Path, typer.Option(help="output directory")] = Path("runs/lab"),
    problem: Annotated[list[str] | None, typer.Option(
        help=f"a problem to run (repeatable; default: all but {', '.join(LAB_LONG)}, which "
        f"take hours a run): {', '.join(LAB_PROBLEMS)}")] = None,
    scheme: Annotated[list[str] | None, typer.Option(
        help="a scheme to run, by its name in the table (repeatable; default: all)")] = None,
    set_: Annotated[list[str] | None, typer.Option(
        "--set", help="an override for every run, e.g. time.end=1e-5")] = None,
    scheduler: Annotated[str | None, typer.Option(
        help="address of an existing Dask scheduler (default: a local cluster)")] = None,
    workers: Annotated[int | None, typer.Option(help="local workers (default: cores)")] = None,
    report_only: Annotated[bool, typer.Option(
        help="tabulate the runs already in OUT, run nothing")] = False,
) -> None:
    """The dissipation lab: every viscosity scheme, with fixed parameters, on every problem
    (docs/dissipation.md).  Writes OUT/lab.json and OUT/lab.md and prints the tables."""
    from .lab import run_lab

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        rows = run_lab(out, problem, scheme, workers=workers, scheduler=scheduler,
                       extra=set_ or [], report_only=report_only)
    except (CaseError, ValueError) as exc:
        _fail(str(exc).splitlines()[0])
    except KeyboardInterrupt:
        _study_interrupted(out)
    typer.echo((out / "lab.md").read_text())
    failed = [f"{r['problem']} / {r['scheme']}: {r['status']}" for r in rows
              if r.get("status") not in ("finished", "ok", None)]
    for line in failed:
        _say(f"note: {line}")


@app.command()
def paper(
    case: Annotated[str, typer.Argument(
        help="a case of one of the paper's examples: a file, or a built-in case "
             "(bars, taylor, cantilever)")] = "bars",
    out: Annotated[Path | None, typer.Option(help="output directory (default "
                                                  "runs/paper-NAME)")] = None,
    workers: Annotated[int | None, typer.Option(help="local workers (default: cores)")] = None,
    scheduler: Annotated[str | None, typer.Option(help="existing Dask scheduler")] = None,
) -> None:
    """Regenerate the paper's figures of the case's example, AC overlaid, and its comparison
    table: the bars, Figs 3-9 and the AV/AC table; the Taylor bar, Figs 11-13; the
    cantilever, Figs 15-17 (the case's analysis chooses)."""
    from .paper import paper_figures

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        out = out or Path("runs") / f"paper-{load_case(case).name}"
        result = paper_figures(case, out, workers=workers, scheduler=scheduler)
    except (CaseError, ValueError) as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        _study_interrupted(out)
    if (out / "table.md").is_file():
        typer.echo((out / "table.md").read_text())
    for fig in result["figures"]:
        typer.echo(f"figure: {fig}")


def _load_run_dir(path: Path) -> dict:
    """A run directory's outputs (:func:`~impactsph.output.load_run`), its case validated;
    refuses (exit code 2) a directory that is not one."""
    import zipfile

    from .loading import validate_case
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
    notes: list[str] = []
    for run, which in zip(runs, ("the run", "its reference run"), strict=False):
        status = run.get("summary", {}).get("status", "finished")
        if status != "finished":  # drawn as far as it went, and said so
            times = run["history"].get("time")  # (a summary "running" says t = 0 until
            reached = float(times[-1]) if times is not None and len(times) else 0.0  # the
            state = {"running": "not finished"}.get(status, status)  # first checkpoint)
            notes.append(f"{which} ({run['path']}) is {state}: its history ends at t = "
                         f"{reached:.6g} s, and its curves there")
    for fig in draw_figures(runs, out, notes=notes):
        typer.echo(f"figure: {fig}")
    for note in notes:
        _say(f"note: {note}")


@app.command()
def animate(
    run_dir: Annotated[Path, typer.Argument(help="a run directory (written by impactsph run)")],
    field: Annotated[str | None, typer.Option(
        help="the field the particles are coloured by: a stored one (density, pressure, "
             "specific_energy, plastic_work, ...), a vector's magnitude or component "
             "(velocity, velocity_x, displacement, displacement_y, speed), von_mises_stress, "
             "deviatoric_stress_xy, ...; default: the case's problem's (taylor: "
             "plastic_work, bars: velocity_x, cantilever: displacement, else speed)")] = None,
    out: Annotated[Path | None, typer.Option(
        help="the file, .mp4 (needs ffmpeg) or .gif (default: RUN_DIR/animation_FIELD.mp4 "
             "where ffmpeg is installed, else .gif)")] = None,
    fps: Annotated[float, typer.Option(help="frames per second")] = 4.0,
    section: Annotated[str, typer.Option(
        help="3D: the axis normal to the mid-plane section drawn (x, y or z)")] = "y",
) -> None:
    """Animate a run's particles coloured by a field, one frame per snapshot
    (output.snapshot_times), with a colour bar and the time: 1D as the field along x, 2D as
    the particles in the plane, 3D as a mid-plane section."""
    from .animate import animate_run

    _load_run_dir(run_dir)
    if not (math.isfinite(fps) and fps > 0.0):  # (0 ended in the GIF writer's division)
        _fail(f"--fps {fps:g}: a number of frames per second > 0")
    try:
        path = animate_run(run_dir, field, out, fps=fps, section=section)
    except CaseError as exc:
        _fail(str(exc))
    typer.echo(f"animation: {path}")


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
    from .figures import case_mismatch, draw_figures
    from .loading import validate_case

    if labels is not None:
        names = [lab.strip() for lab in labels.split(",")]
        if len(names) != len(run_dirs):
            _fail(f"--labels gives {len(names)} label{'' if len(names) == 1 else 's'} for "
                  f"{len(run_dirs)} runs")
    else:
        names = [d.name or str(d) for d in run_dirs]
        if len(set(names)) != len(names):
            names = [str(d) for d in run_dirs]
    runs = [_load_run_dir(d) for d in run_dirs]
    mismatch = case_mismatch([validate_case(r["case"]) for r in runs])
    if mismatch is not None:
        typer.echo(f"note: {mismatch}; only the kinetic energy and the energies are "
                   f"overlaid", err=True)
    out.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    for fig in draw_figures(runs, out, names, notes=notes):
        typer.echo(f"figure: {fig}")
    for note in notes:
        _say(f"note: {note}")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)[:40]


def _help_of(doc: str) -> str:
    """A command's docstring as its help: each paragraph on one line, so that the terminal
    wraps it (typer shows the line breaks of every paragraph but the first as they are, and
    those of the first in the commands' list), and its brackets kept as text (typer reads the
    help as rich markup, which took ``[materials.X]`` for a style and dropped it)."""
    import typer.core
    from rich.markup import escape

    markup = typer.core.HAS_RICH and app.rich_markup_mode == "rich"  # (TYPER_USE_RICH=0: no)
    paragraphs = (" ".join(line.strip() for line in p.splitlines())
                  for p in inspect.cleandoc(doc).split("\n\n"))
    return "\n\n".join(escape(p) if markup else p for p in paragraphs)


for _command in app.registered_commands:
    if _command.help is None and _command.callback is not None and _command.callback.__doc__:
        _command.help = _help_of(_command.callback.__doc__)


def main() -> None:  # pragma: no cover
    """Entry point for ``python -m impactsph``."""
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
