"""Run a case end to end: simulate, write every output, analyse, draw the figures.

Nothing is lost on interruption: ``history.csv`` and ``probes.csv`` grow as the run goes
(:class:`~impactsph.output.HistoryStream`), ``summary.json`` is written when the run starts,
at each checkpoint and at the end with the run's ``status``, checkpoints are written every
``output.checkpoint_interval`` of simulated time or, without one, every
:data:`CHECKPOINT_WALL_SECONDS` of wall time, and a run asked to stop (``stop``, e.g. by
:func:`~impactsph.interrupt.stop_on_signals` on Ctrl-C or SIGTERM) stops after a whole step
with a checkpoint to continue from (:class:`~impactsph.errors.RunInterrupted`).
"""

from __future__ import annotations

import logging
import time as _time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ._version import __version__
from .config import Case
from .errors import DeviceMemoryError, RunInterrupted
from .interrupt import StopRequest
from .loading import validated_again
from .measures import run_measures
from .output import (
    HistoryStream,
    load_run,
    write_case,
    write_snapshots,
    write_summary,
)
from .preflight import label_of, reference_run, scheme_line
from .problems.registry import analyse
from .rundir import IfExists, RunLock, check_run_dir, clear_outputs, make_run_dir, remove_if_empty
from .runlog import held_records, run_log
from .simulation import RunRecord, Simulation, SimulationError

log = logging.getLogger("impactsph")

#: without ``output.checkpoint_interval``, a checkpoint is written after the first step that
#: ends this many seconds of wall time after the stepping began or after the previous
#: checkpoint: none for a run that takes less, and the last one removed when the run
#: finishes (its outputs are then complete)
CHECKPOINT_WALL_SECONDS = 300.0


class _Stop(Exception):  # noqa: N818 (not an error)
    """Raised after a step to leave the run loop on a stop request."""


class PeriodicOutputs:
    """ParaView snapshots and checkpoints every so much simulated time (``output``'s
    ``vtk_interval`` and ``checkpoint_interval``), written after the first step at or past
    each multiple of the interval; without ``checkpoint_interval``, checkpoints every
    ``wall_seconds`` of wall time (None: none).  With each checkpoint, ``snapshots.npz`` and a
    ``summary.json`` with ``status`` ``running``."""

    def __init__(self, sim: Simulation, out: Path,
                 wall_seconds: float | None = CHECKPOINT_WALL_SECONDS):
        o = sim.case.output
        self.out = out
        self.vtk = None
        t = sim.state.time
        if o.vtk_interval is not None:
            from .vtk import VTKSeries

            self.vtk = VTKSeries(out / "vtk", binary=o.vtk_format == "binary")
            if t > 0:
                self.vtk.resume(t)
            else:
                self.vtk.write(sim)
            self.next_vtk = (int(t / o.vtk_interval + 1e-9) + 1) * o.vtk_interval
        if o.checkpoint_interval is not None:
            self.next_checkpoint = (int(t / o.checkpoint_interval + 1e-9) + 1
                                    ) * o.checkpoint_interval
        self.wall_seconds = wall_seconds if o.checkpoint_interval is None else None
        self.last_checkpoint = _time.perf_counter()

    def __call__(self, sim: Simulation) -> None:
        o, t = sim.case.output, sim.time  # the time alone: no download of a GPU state
        if self.vtk is not None and t >= self.next_vtk * (1 - 1e-12):
            self.vtk.write(sim)
            while self.next_vtk <= t * (1 + 1e-12):
                self.next_vtk += o.vtk_interval
        if o.checkpoint_interval is not None and t >= self.next_checkpoint * (1 - 1e-12):
            self.checkpoint(sim)
            while self.next_checkpoint <= t * (1 + 1e-12):
                self.next_checkpoint += o.checkpoint_interval
        elif (self.wall_seconds is not None
              and _time.perf_counter() - self.last_checkpoint >= self.wall_seconds):
            self.checkpoint(sim)

    def checkpoint(self, sim: Simulation, status: str = "running") -> Path:
        """Write ``checkpoint.h5``, then ``snapshots.npz`` and a summary with ``status``."""
        from .checkpoint import write_checkpoint

        path = write_checkpoint(sim, self.out / "checkpoint.h5")
        write_snapshots(self.out, sim)
        write_summary(self.out, {"status": status, **sim.summary(), "checkpoint": str(path)})
        self.last_checkpoint = _time.perf_counter()
        if status == "running":
            log.info("checkpoint at t = %g s (step %d)", sim.state.time, sim.state.step)
        return path

    def finish(self, sim: Simulation) -> None:
        """The last ParaView snapshot, at the end time (unless just written)."""
        if self.vtk is not None and (not self.vtk.entries
                                     or self.vtk.entries[-1][0] < sim.state.time):
            self.vtk.write(sim)


def compiling_note(record: RunRecord) -> str:
    """``", 4.4 s of it numba compiling or loading code"`` where that was a tenth of the run's
    wall time or more and 0.1 s or more (a first run, or a short one after an upgrade), else
    nothing."""
    if record.compile_seconds >= max(0.1 * record.wall_seconds, 0.1):
        return f", {record.compile_seconds:.3g} s of it numba compiling or loading code"
    return ""


def check_out(out: Path | str, if_exists: IfExists, restarting: bool, case: Case) -> None:
    """:func:`run_case`'s refusals of ``out`` (:func:`~impactsph.rundir.check_run_dir`):
    by ``if_exists``, except that a run continued from a checkpoint may write into a
    directory that holds its own run where ``"refuse"`` is asked, and into no other
    (:func:`~impactsph.checkpoint.check_restart_out`).  ``impactsph run`` calls it before
    its preflight too, so that a refusal is its only line."""
    check_run_dir(out, "keep" if restarting and if_exists == "refuse" else if_exists)
    if restarting and if_exists == "refuse":
        from .checkpoint import check_restart_out

        check_restart_out(out, case)


def run_case(case: Case, out: Path | str, *, callback: Callable[[Simulation], None] | None = None,
             figures: bool | None = None, restart: Path | str | None = None,
             if_exists: IfExists = "keep", stop: Callable[[], bool] | None = None,
             checkpoint_wall_seconds: float | None = CHECKPOINT_WALL_SECONDS
             ) -> dict[str, Any]:
    """Run ``case`` and write its outputs into ``out``; with ``restart``, continue from that
    checkpoint instead of starting at t = 0.  Returns the summary.

    ``out`` belongs to this run while it goes (``out/.lock``; :mod:`.rundir`): a directory in
    use by another run is refused, and so, by ``if_exists``, one that already holds
    something: ``"keep"`` (the default, for library callers and sweeps) writes over what is
    there, ``"refuse"`` (``impactsph run``) refuses it unless ``restart`` is given,
    ``"overwrite"`` removes the previous run's outputs first.  These refusals, a checkpoint
    that cannot be used and a case that cannot be set up come before any work and leave no
    directory behind (:class:`~impactsph.errors.OutputError`,
    :class:`~impactsph.errors.CaseError`).

    ``stop()`` is asked after every step; when it says True the run stops there, writes
    ``checkpoint.h5``, its history and a summary with ``status`` ``interrupted``, and raises
    :class:`~impactsph.errors.RunInterrupted`.  ``checkpoint_wall_seconds``: without
    ``output.checkpoint_interval``, write a checkpoint every this much wall time (None:
    never).  On an instability the history written so far is kept, and
    :class:`SimulationError` is raised."""
    case = validated_again(case, "run_case(case)")
    if if_exists not in ("keep", "refuse", "overwrite"):
        raise ValueError(f"run_case(if_exists = {if_exists!r}): 'keep', 'refuse' or "
                         f"'overwrite'")
    if callback is not None and not callable(callback):
        raise TypeError(f"run_case(callback = {callback!r}): a function of the simulation, "
                        f"callback(sim), or None")
    out = Path(out)
    check_out(out, if_exists, restart is not None, case)
    checked: list = []  # the checkpoint's verification's log lines, for run.log
    if restart is not None:
        from .checkpoint import verify_checkpoint

        with held_records() as checked:
            verify_checkpoint(restart, case)
    created = make_run_dir(out)
    lock = RunLock(out)
    try:
        lock.acquire()
        # a case that cannot be set up (CaseError) leaves no directory; its set-up's log
        # lines go to run.log once that is open
        with held_records() as setup_lines:
            if restart is not None:
                from .checkpoint import load_checkpoint

                sim = load_checkpoint(restart, case, verify=False)
            else:
                sim = Simulation(case)
        if isinstance(stop, StopRequest):
            stop.arm()  # set up: a signal now asks for a stop after a step
        if if_exists == "overwrite":
            clear_outputs(out)
        with run_log(out, earlier=[*checked, *setup_lines]):
            if restart is not None:
                written_by = sim.record.restarts[-1]["impactsph"]
                log.info("restarted from %s at t = %g s (step %d), a checkpoint of impactsph "
                         "%s", restart, sim.state.time, sim.state.step, written_by)
                if written_by != __version__:
                    log.warning("%s was written by impactsph %s and is continued by %s: the "
                                "history to t = %g s is that version's (summary.json: "
                                "restarts)", restart, written_by, __version__, sim.state.time)
            return _run(sim, case, out, callback=callback, figures=figures, stop=stop,
                        checkpoint_wall_seconds=checkpoint_wall_seconds)
    finally:
        lock.release()
        if created:
            remove_if_empty(out)


def _run(sim: Simulation, case: Case, out: Path, *,
         callback: Callable[[Simulation], None] | None, figures: bool | None,
         stop: Callable[[], bool] | None, checkpoint_wall_seconds: float | None
         ) -> dict[str, Any]:
    """:func:`run_case` once the directory is this run's and the simulation is set up."""
    write_case(out, case)
    stream = HistoryStream(out, sim)
    write_summary(out, {"status": "running", **sim.summary()})
    periodic = PeriodicOutputs(sim, out, checkpoint_wall_seconds)

    def after_step(s: Simulation) -> None:
        stream.update(s)
        periodic(s)
        if callback is not None:
            callback(s)
        if stop is not None and stop():
            raise _Stop

    log.info("%s: %d particles, %dD, to t = %g s", case.name, sim.state.n, sim.state.dim,
             case.time.end)
    log.info("%s", scheme_line(case))
    try:
        if stop is not None and stop():  # asked while the run was being set up
            raise _Stop
        sim.run(callback=after_step)
    except _Stop:
        stream.update(sim)
        stream.close()
        path = periodic.checkpoint(sim, "interrupted")
        t, step = sim.state.time, sim.state.step
        raise RunInterrupted(f"interrupted at t = {t:.6e} s, step {step}; checkpoint {path}",
                             time=t, step=step, checkpoint=str(path)) from None
    except SimulationError as exc:
        stream.update(sim)
        stream.close()
        write_snapshots(out, sim)
        status = "out_of_memory" if isinstance(exc, DeviceMemoryError) else "unstable"
        write_summary(out, {"status": status, **sim.summary()})
        raise
    except KeyboardInterrupt:  # stopped at once, mid-step: no checkpoint of this state
        stream.close()
        write_summary(out, {"status": "interrupted", **sim.summary()})
        raise
    except BaseException:
        stream.close(sync=False)
        raise
    stream.update(sim)
    stream.close()
    periodic.finish(sim)
    write_snapshots(out, sim)
    log.info("finished: t = %g s, %d steps, %.3g s of wall time%s", sim.state.time,
             sim.state.step, sim.record.wall_seconds, compiling_note(sim.record))
    summary = finished_summary(sim)
    write_summary(out, summary)  # before the figures, which read it back (load_run)
    if case.output.checkpoint_interval is None:  # complete: no automatic checkpoint kept
        (out / "checkpoint.h5").unlink(missing_ok=True)
    if case.output.figures if figures is None else figures:

        def stopped(reference: RunInterrupted | None = None) -> RunInterrupted:
            during = (f"; its reference run ({out / 'reference'}) stopped at t = "
                      f"{reference.time:.6e} s, and impactsph plot draws it as far as it went"
                      if reference is not None else "")
            return RunInterrupted(
                f"interrupted after the run finished (t = {sim.state.time:.6e} s, step "
                f"{sim.state.step}); the figures were not drawn{during}", time=sim.state.time,
                step=sim.state.step, checkpoint=None, finished=True)

        if stop is not None and stop():
            raise stopped()
        runs = [load_run(out)]
        ref = reference_run(case, figures=True)
        if ref is not None:
            ref_case = case.model_copy(update={
                "viscosity": ref,
                "output": case.output.model_copy(update={"figures": False,
                                                         "reference_viscosity": None})})
            log.info("reference run with %s, into %s", label_of(ref_case), out / "reference")
            try:
                run_case(ref_case, out / "reference", figures=False, stop=stop,
                         checkpoint_wall_seconds=checkpoint_wall_seconds)
                runs.append(load_run(out / "reference"))
            except RunInterrupted as exc:
                raise stopped(exc) from None
            except SimulationError as exc:  # the run itself is complete: drawn without it
                note = (f"reference run ({label_of(ref_case)}): unstable ({exc}); the "
                        f"figures are drawn without it")
                log.warning("%s", note)
                summary["notes"].append(note)
        from .figures import draw_figures  # matplotlib: imported where a run draws

        summary["figures"] = [str(p) for p in draw_figures(runs, out, notes=summary["notes"])]
        write_summary(out, summary)  # again, with the list of figures
    for note in summary["notes"]:
        log.info("note (%s): %s", out, note)
    return summary


def finished_summary(sim: Simulation) -> dict[str, Any]:
    """The summary of a finished run: the run-wide numbers, the measures of every body and
    gauge (:func:`~impactsph.measures.run_measures`), the problem's metrics
    (:func:`~impactsph.problems.analyse`), and ``notes``: what could not be measured, and
    why (a measure or an analysis that fails is a note, never an exception)."""
    generic = run_measures(sim)
    metrics = analyse(sim.case.analysis, sim)
    notes = [*generic.pop("notes"), *metrics.pop("notes", [])]
    return {"status": "finished", **sim.summary(), **generic, **metrics, "notes": notes}
