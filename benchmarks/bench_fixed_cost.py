"""What a time step costs whatever the particle count: the paper's Taylor bar with 3 x 9
particles (27, against the paper's 21 x 67), whose passes have almost nothing to do, so that
a step's time is its fixed part: the Python between the passes, the passes' dispatch and the
threads' hand-over.  On the paper's bar (1,407 particles) that part is a sixth of a step;
on the cantilever's 151,376 steps it is a fifth of the run.

    .venv/bin/python benchmarks/bench_fixed_cost.py                       # this tree
    .venv/bin/python benchmarks/bench_fixed_cost.py --trees /tmp/before   # beside another
    .venv/bin/python benchmarks/bench_fixed_cost.py --threads 1 2 --rounds 4 --json out.json

Each worker (a process of its own, ``TREE/src`` as its impactsph) runs the small bar to
0.2 ms (compiling or loading its code), then five pieces of 0.4 ms each, and reports the
best piece's microseconds a step.  With ``--trees`` the trees alternate round by round, so
that a slow spell of the machine falls on all of them; the table gives each tree's median
and range over the rounds.  The same tree measured twice this way agreed within 5%
(benchmarks/README.md, "A small step's fixed cost").
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from _trees import alternated  # noqa: E402

#: the small bar: the paper's case with 3 x 9 particles
OVERRIDES = ("bodies.0.geometry.count=[3,9]",)
WARM_UP, PIECE, PIECES = 2e-4, 4e-4, 5


def worker(threads: int) -> dict:
    """The best piece's microseconds a step of the small bar on ``threads`` threads."""
    from impactsph import Simulation, __version__, load_case

    case = load_case("taylor", [*OVERRIDES, f"compute.threads={threads}"])
    sim = Simulation(case)
    sim.run(WARM_UP)
    best = float("inf")
    for _ in range(PIECES):
        first, start = sim.step, time.perf_counter()
        sim.run(sim.time + PIECE)
        best = min(best, (time.perf_counter() - start) / (sim.step - first))
    return {"us_per_step": 1e6 * best, "particles": sim.state.n, "version": __version__}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--trees", type=Path, nargs="*", default=[],
                    help="other source trees, timed beside this one")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", type=Path, help="write the rows here too")
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.threads[0])))
        return 0
    trees = [ROOT, *[t.resolve() for t in args.trees]]
    rows = []
    for threads in args.threads:
        results = alternated(__file__, trees, [threads],
                             lambda t: ["--threads", str(t)], args.rounds, threads)
        for tree in trees:
            times = [r["us_per_step"] for r in results[(str(tree), threads)]]
            rows.append({"tree": str(tree), "threads": threads,
                         "median_us_per_step": statistics.median(times),
                         "min": min(times), "max": max(times), "rounds": times})
    print(f"python {platform.python_version()}, {platform.machine()}; the Taylor bar with "
          f"3 x 9 particles, best of {PIECES} pieces of {PIECE * 1e3:g} ms a worker, "
          f"{args.rounds} rounds alternated")
    print(f"{'tree':40s} {'threads':>7s} {'us a step (median)':>19s} {'range':>16s}")
    for r in rows:
        print(f"{r['tree'][-40:]:40s} {r['threads']:7d} {r['median_us_per_step']:19.1f} "
              f"{r['min']:7.1f}-{r['max']:<8.1f}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
