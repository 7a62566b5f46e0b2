"""Run a case end to end: simulate, write every output, analyse, draw the figures."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .config import Case
from .figures import draw_figures
from .output import load_run, write_case, write_history, write_snapshots, write_summary
from .plotting import label_of
from .problems.registry import analyse
from .simulation import Simulation, SimulationError

log = logging.getLogger("impactsph")


class PeriodicOutputs:
    """ParaView snapshots and checkpoints every so much simulated time (``output``'s
    ``vtk_interval`` and ``checkpoint_interval``), written after the first step at or past
    each multiple of the interval."""

    def __init__(self, sim: Simulation, out: Path):
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

    def __call__(self, sim: Simulation) -> None:
        o, t = sim.case.output, sim.state.time
        if self.vtk is not None and t >= self.next_vtk * (1 - 1e-12):
            self.vtk.write(sim)
            while self.next_vtk <= t * (1 + 1e-12):
                self.next_vtk += o.vtk_interval
        if o.checkpoint_interval is not None and t >= self.next_checkpoint * (1 - 1e-12):
            from .checkpoint import write_checkpoint

            write_checkpoint(sim, self.out / "checkpoint.h5")
            log.info("checkpoint at t = %g s (step %d)", t, sim.state.step)
            while self.next_checkpoint <= t * (1 + 1e-12):
                self.next_checkpoint += o.checkpoint_interval

    def finish(self, sim: Simulation) -> None:
        """The last ParaView snapshot, at the end time (unless just written)."""
        if self.vtk is not None and (not self.vtk.entries
                                     or self.vtk.entries[-1][0] < sim.state.time):
            self.vtk.write(sim)


def run_case(case: Case, out: Path | str, *, callback: Callable[[Simulation], None] | None = None,
             figures: bool | None = None, restart: Path | str | None = None) -> dict[str, Any]:
    """Run ``case`` and write its outputs into ``out``; with ``restart``, continue from that
    checkpoint instead of starting at t = 0.  Returns the summary.  On an instability the
    history written so far is kept, and :class:`SimulationError` is raised."""
    out = Path(out)
    # a case that cannot be set up (CaseError) leaves no directory
    if restart is not None:
        from .checkpoint import load_checkpoint

        sim = load_checkpoint(restart, case)
    else:
        sim = Simulation(case)
    out.mkdir(parents=True, exist_ok=True)
    write_case(out, case)
    periodic = PeriodicOutputs(sim, out)

    def after_step(s: Simulation) -> None:
        periodic(s)
        if callback is not None:
            callback(s)

    log.info("%s: %d particles, %dD, to t = %g s", case.name, sim.state.n, sim.state.dim,
             case.time.end)
    try:
        sim.run(callback=after_step)
    except SimulationError:
        write_history(out, sim)
        write_snapshots(out, sim)
        write_summary(out, sim.summary())
        raise
    periodic.finish(sim)
    write_history(out, sim)
    write_snapshots(out, sim)
    summary = {**sim.summary(), **analyse(case.analysis, sim)}
    write_summary(out, summary)  # before the figures, which read it back (load_run)
    if case.output.figures if figures is None else figures:
        runs = [load_run(out)]
        ref = case.output.reference_viscosity
        if ref is not None and ref != case.viscosity:
            ref_case = case.model_copy(update={
                "viscosity": ref,
                "output": case.output.model_copy(update={"figures": False,
                                                         "reference_viscosity": None})})
            log.info("reference run with %s", label_of(ref_case))
            run_case(ref_case, out / "reference", figures=False)
            runs.append(load_run(out / "reference"))
        summary["figures"] = [str(p) for p in draw_figures(runs, out)]
        write_summary(out, summary)  # again, with the list of figures
    return summary
