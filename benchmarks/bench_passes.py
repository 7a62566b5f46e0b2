"""Time each compiled pass of a rate evaluation on its own (ms, best of ``--repeat`` steps),
here and, side by side in the same run, in other source trees.

    .venv/bin/python benchmarks/bench_passes.py [--trees /tmp/head] [--dims 2 3] [--n 1e5]
        [--threads 1] [--rounds 2] [--repeat 10]

The case is ``bench_ac_cost.py``'s lattice (dx = 1 mm, h = 1.2 dx, elastic steel, random
velocities of about 1 m/s) with AC and the stabilisation of an elastic case's defaults, set
explicitly (the kernel gradient correction of the velocity gradient and the forces, the
hourglass control), so that every pass runs: particle, moment, pair, correction,
hourglass.  Each tree and dimension runs in a new process (``PYTHONPATH=TREE/src``), the
trees alternating within each round, so that a busy spell of a shared machine falls on
both.  Each pass is timed by a
wrapper around the compiled function that the solver calls.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
TIMED = ("particle_pass", "own_order_particle_pass", "moment_pass", "pair_pass", "correction_pass",
         "hourglass_pass")
#: the passes the rates run in shares (impactsph.physics.chunked.run_chunked)
CHUNKED = {"moment_pass", "pair_pass", "hourglass_pass"}
STABILISATION = {"gradient_correction": "velocity_gradient_and_forces", "hourglass": 2.0}


def _timer(function, name: str, times: dict[str, list[float]]):
    def timed(*args):
        t0 = time.perf_counter()
        function(*args)
        times.setdefault(name, []).append(time.perf_counter() - t0)
    return timed


def measure(dim: int, n: int, repeat: int) -> dict[str, float]:
    """The best time of each pass (s) in this process's impactsph."""
    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_ac_cost import lattice_case

    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    case = lattice_case(dim, n, "ac")
    case["stabilisation"] = STABILISATION
    sim = Simulation(validate_case(case))
    sim.state.velocity[:] = np.random.default_rng(1).normal(size=sim.state.velocity.shape)
    dt = 0.1 * stable_time_step(sim.state, sim.problem.table, 0.3)
    backend = sim.solver.backend
    # the run's passes and, since 2026-12-04, the module of its neighbour loops where every h
    # is the same (CpuRates.neighbour_loops; this lattice's are): each pass is called from one
    modules = [backend.passes]
    if hasattr(backend, "neighbour_loops"):
        modules.append(backend.neighbour_loops(True))
    times: dict[str, list[float]] = {}
    # the passes run in shares are timed where the rates hand them to run_chunked: a wrapper
    # in a pass's place would run its shares one after another (run_chunked's docstring), so
    # with --threads above 1 this timed half a pass, serially, before 2026-12-06
    from impactsph.physics import rates as rates_module
    run_chunked = rates_module.run_chunked

    def timed_chunked(chunk_pass, *args):
        t0 = time.perf_counter()
        run_chunked(chunk_pass, *args)
        name = getattr(chunk_pass, "__name__", "")
        if name in TIMED:
            times.setdefault(name, []).append(time.perf_counter() - t0)
    rates_module.run_chunked = timed_chunked
    for passes in modules:  # (the wrappers stay: this worker process ends after the steps)
        for pass_name in set(TIMED) - CHUNKED:
            if hasattr(passes, pass_name):  # (a tree before own_order_particle_pass has none)
                setattr(passes, pass_name, _timer(getattr(passes, pass_name), pass_name, times))
    sim.integrator.step(sim.state, dt)  # compiles
    times.clear()
    for _ in range(repeat):
        sim.integrator.step(sim.state, dt)
    return {pass_name: min(values) for pass_name, values in times.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trees", nargs="*", default=[], help="other source trees to compare")
    ap.add_argument("--dims", type=int, nargs="+", default=[2, 3])
    ap.add_argument("--n", type=float, default=1e5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.dims[0], int(args.n), args.repeat)))
        return 0
    from _trees import alternated

    trees = [HERE.parent] + [Path(t).resolve() for t in args.trees]
    # the threaded passes, as before 2026-12-05, unless the caller chose: with one numba
    # thread and the variable unset, a run now compiles the serial ones
    results = alternated(__file__, trees, args.dims,
                         lambda dim: ["--dims", str(dim), "--n", str(args.n), "--repeat",
                                      str(args.repeat)],
                         args.rounds, args.threads, IMPACTSPH_PARALLEL="1")
    print(f"{args.threads} thread(s), about {args.n:.0e} particles, best of {args.repeat} "
          f"steps per process, ms (a column per round; trees separated by |)")
    for dim in args.dims:
        here = results[(str(trees[0]), dim)]
        for key in sorted(here[0]):
            row = [f"{dim}D {key:<16}"]
            for tree in trees:
                runs = results[(str(tree), dim)]
                row.append(" ".join(f"{r[key] * 1e3:8.2f}" if key in r else "       -"
                                    for r in runs))
            if len(trees) > 1 and all(key in r for r in results[(str(trees[1]), dim)]):
                ratio = (min(r[key] for r in here)
                         / min(r[key] for r in results[(str(trees[1]), dim)]))
                row.append(f"best here / best {trees[1].name}: {ratio:.2f}")
            print(" | ".join(row))
    print("columns: " + " | ".join(str(t) for t in trees))
    return 0


if __name__ == "__main__":
    sys.exit(main())
