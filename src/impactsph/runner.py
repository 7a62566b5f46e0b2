"""Run a case end to end: simulate, write every output, analyse, draw the figures."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .analysis import analyse
from .config import Case
from .figures import draw_figures
from .output import load_run, write_case, write_history, write_snapshots, write_summary
from .plotting import label_of
from .simulation import Simulation, SimulationError

log = logging.getLogger("impactsph")


def run_case(case: Case, out: Path | str, *, callback: Callable[[Simulation], None] | None = None,
             figures: bool | None = None) -> dict[str, Any]:
    """Run ``case`` and write its outputs into ``out``.  Returns the summary.  On an
    instability the history written so far is kept, and :class:`SimulationError` is raised."""
    out = Path(out)
    sim = Simulation(case)  # a case that cannot be set up (CaseError) leaves no directory
    out.mkdir(parents=True, exist_ok=True)
    write_case(out, case)
    log.info("%s: %d particles, %dD, to t = %g s", case.name, sim.state.n, sim.state.dim,
             case.time.end)
    try:
        sim.run(callback=callback)
    except SimulationError:
        write_history(out, sim)
        write_snapshots(out, sim)
        write_summary(out, sim.summary())
        raise
    write_history(out, sim)
    write_snapshots(out, sim)
    summary = {**sim.summary(), **analyse(case.analysis, sim)}
    write_summary(out, summary)
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
        write_summary(out, summary)
    return summary
