"""Where a small run's time step goes: each compiled pass, the integrator's kernels, the
neighbour list, the ghosts' fill, the survey and the history, in microseconds per step.

Issue 16 asks for the paper's Taylor bar (1,407 particles, 2D) to 50 us in at most 1.0 s.
This script runs a case to its end once per thread count, with a timer around each part
(the run's own functions, wrapped in this process only), and prints what each part costs per
step and what is left for Python between them.  The timers cost about half a microsecond a
call, some 10-15 us a step; the table's "run (wall)" includes them.

    .venv/bin/python benchmarks/bench_step_anatomy.py            # the Taylor bar, 1 and 2 threads
    .venv/bin/python benchmarks/bench_step_anatomy.py cantilever --set time.end=2e-4
    .venv/bin/python benchmarks/bench_step_anatomy.py --threads 2 --json step.json
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

from impactsph import Simulation, __version__, load_case
from impactsph import integrate as integrate_module
from impactsph import solver as solver_module
from impactsph.neighbours import NeighbourList
from impactsph.physics import rates as rates_module
from impactsph.physics import total_lagrangian

#: (label, parent) of each timed part, in the table's order; a part's parent holds its time
PARTS = (("run (wall)", None), ("step", "run (wall)"), ("survey", "run (wall)"),
         ("survey kernel", "survey"), ("history row", "run (wall)"))


class Timers:
    """Seconds and calls per label; :meth:`wrap` puts a timer around an attribute."""

    def __init__(self) -> None:
        self.seconds: Counter[str] = Counter()
        self.calls: Counter[str] = Counter()
        self._undo: list[tuple[Any, str, Any, bool]] = []

    def wrap(self, owner: Any, name: str, label: str | Callable[[tuple], str]) -> None:
        """A timer around the attribute, under ``label``, or ``label(args)`` of each call
        (``run_chunked``'s timer names the pass it runs: the chunked passes themselves must
        stay numba dispatchers, or ``run_chunked`` runs their shares one after another)."""
        function = getattr(owner, name)
        seconds, calls, clock = self.seconds, self.calls, time.perf_counter

        def timed(*args: Any, **kwargs: Any) -> Any:
            key = label if isinstance(label, str) else label(args)
            start = clock()
            try:
                return function(*args, **kwargs)
            finally:
                seconds[key] += clock() - start
                calls[key] += 1

        own = vars(owner)  # the owner's own attribute (module, class or instance), if any
        self._undo.append((owner, name, own[name] if name in own else None, name in own))
        setattr(owner, name, timed)

    def restore(self) -> None:
        """Every wrapped attribute as it was."""
        for owner, name, original, had_own in reversed(self._undo):
            if had_own:
                setattr(owner, name, original)
            else:  # an instance's bound method: the class's again
                delattr(owner, name)
        self._undo.clear()


def _chunked(compiled: Any) -> bool:
    """Whether ``compiled`` is a chunked pass: ``(first, step, ...)``."""
    py_func = getattr(compiled, "py_func", None)
    return py_func is not None and py_func.__code__.co_varnames[:2] == ("first", "step")


def instrument(sim: Simulation, timers: Timers) -> list[tuple[str, str]]:
    """Timers around the parts of ``sim``'s step; returns the (label, parent) of each."""
    parts = list(PARTS)
    integrator, solver = sim.integrator, sim.solver
    passes = solver.backend.passes
    # and the module of the neighbour loops where every h is the same (CpuRates.neighbour_loops):
    # each pass is called from one of the two, timed under its name either way
    modules = [passes]
    if hasattr(solver.backend, "neighbour_loops"):
        modules.append(solver.backend.neighbour_loops(True))
    # the chunked passes (the switch's own module's too) are timed around run_chunked
    for module in (rates_module, total_lagrangian):
        timers.wrap(module, "run_chunked", lambda args: args[0].__name__)
    for name in sorted(dir(passes)):  # every compiled pass this module has
        if name.endswith("_pass") and callable(getattr(passes, name)):
            if not _chunked(getattr(passes, name)):
                for module in modules:
                    timers.wrap(module, name, name)
            parts.append((name, "step"))
    # the total-Lagrangian passes (run_chunked's too; shown where they ran)
    parts += [("deformation_pass", "step"), ("force_pass", "step")]
    steps: list[tuple[Any, str, str]] = [
        # (around run_stage, not the pass: a chunked pass must stay a numba dispatcher, or
        # run_chunked runs its shares one after another)
        (integrate_module, "run_stage", "stage (update, return map, walls, survey)"),
        (integrator, "_keep", "start copies"),
        (integrator, "_constrain", "walls' constraint (SSP-RK3's combinations)"),
        (solver, "_build", "neighbour list rebuild"),
        (NeighbourList, "stale", "neighbour list check"),
        (solver, "_fill", "ghosts' fill (copies, fill_ghosts)"),
        (solver_module, "serial_rate_totals", "rate totals"),
        (solver_module, "rate_totals", "rate totals"),
    ]
    for owner, name, label in steps:
        if hasattr(owner, name):
            timers.wrap(owner, name, label)
            if (label, "step") not in parts:
                parts.append((label, "step"))
    timers.wrap(solver_module, "fill_ghosts", "fill_ghosts")
    parts.append(("fill_ghosts", "ghosts' fill (copies, fill_ghosts)"))
    timers.wrap(integrator, "step", "step")
    timers.wrap(integrator, "survey_kernel", "survey kernel")
    timers.wrap(sim, "_survey", "survey")
    timers.wrap(sim, "_record_row", "history row")
    return parts


def anatomy(case_name: str, overrides: list[str], threads: int) -> dict[str, Any]:
    """One run of the case to its end with ``threads`` threads (after a short run of a copy
    that loads or compiles the kernels); each part's microseconds and calls per step."""
    case = load_case(case_name, ["output.figures=false", f"compute.threads={threads}",
                                 *overrides])
    warm = Simulation(case)  # a step of a copy first: the compiled code loaded (or compiled)
    warm.run(t_end=1e-3 * case.time.end)
    sim = Simulation(case)
    timers = Timers()
    try:
        parts = instrument(sim, timers)
        start = time.perf_counter()
        sim.run()
        wall = time.perf_counter() - start
    finally:
        timers.restore()  # (also after a failure part way: the passes module is shared)
    timers.seconds["run (wall)"] = wall
    steps = max(timers.calls["step"], 1)
    rows = []
    for label, parent in parts:
        if not timers.calls[label] and label != "run (wall)":
            continue
        rows.append({"part": label, "parent": parent,
                     "us_per_step": 1e6 * timers.seconds[label] / steps,
                     "calls_per_step": timers.calls[label] / steps})
    for parent in ("run (wall)", "step"):  # what no timer holds: Python between the parts
        inner = sum(r["us_per_step"] for r in rows if r["parent"] == parent)
        whole = next(r["us_per_step"] for r in rows if r["part"] == parent)
        rows.append({"part": f"{parent}: the rest (Python)", "parent": parent,
                     "us_per_step": whole - inner, "calls_per_step": 0.0})
    return {"case": case_name, "overrides": overrides, "threads": threads,
            "particles": sim.state.n, "steps": steps, "wall_seconds": wall,
            "pair_evaluations_per_step": sim.solver.pair_evaluations / max(sim.state.step, 1),
            "parts": rows}


def print_table(result: dict[str, Any]) -> None:
    print(f"\n{result['case']} {' '.join(result['overrides'])}: {result['particles']} particles, "
          f"{result['steps']} timed steps, {result['threads']} thread(s), "
          f"{result['wall_seconds']:.2f} s, "
          f"{result['pair_evaluations_per_step']:.0f} pair evaluations a step")
    step = next(r["us_per_step"] for r in result["parts"] if r["part"] == "step")
    print(f"{'part':48s} {'us/step':>9s} {'calls':>6s} {'of step':>8s}")

    def show(parent: str | None, depth: int) -> None:  # each part, then its parts
        for row in result["parts"]:
            if row["parent"] != parent:
                continue
            calls = f"{row['calls_per_step']:6.1f}" if row["calls_per_step"] else " " * 6
            print(f"{'  ' * depth + row['part']:48s} {row['us_per_step']:9.1f} {calls} "
                  f"{row['us_per_step'] / step:8.1%}")
            show(row["part"], depth + 1)

    show(None, 0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("case", nargs="?", default="taylor")
    parser.add_argument("--set", nargs="*", default=[], dest="overrides",
                        help="overrides, e.g. time.end=2e-4")
    parser.add_argument("--threads", nargs="*", type=int, default=[1, 2])
    parser.add_argument("--json", help="write every number here")
    args = parser.parse_args(argv)
    results = []
    print(f"impactsph {__version__}, python {platform.python_version()}, "
          f"{platform.machine()}; {time.strftime('%Y-%m-%dT%H:%M:%S')}")
    for threads in args.threads:
        result = anatomy(args.case, args.overrides, threads)
        print_table(result)
        results.append(result)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"version": __version__, "results": results}, f, indent=1)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
