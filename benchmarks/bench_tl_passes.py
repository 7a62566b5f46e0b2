"""Time the total-Lagrangian passes (deformation, force) of the stabilised beam on their own
(us per call, best and median of the timed steps), here and, side by side in the same run,
in other source trees.

    .venv/bin/python benchmarks/bench_tl_passes.py [--trees /tmp/head] [--depth 10 20]
        [--threads 1] [--rounds 2] [--steps 400]

The case is ``validation/beam.py``'s cantilever with ``formulation = "total_lagrangian"``
(``--depth`` particles through the depth, 12 times as many along it; the first mode's
velocity as in ``beam.measure``), so the passes see a bending beam with the hourglass
penalty and the artificial viscosity on.  Each tree and depth runs in a new process
(``PYTHONPATH=TREE/src``), the trees alternating within each round.  The pair evaluations
per second are the reference list's entries over the force pass's best time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
TIMED = ("deformation_pass", "force_pass")


def measure(depth: int, steps: int) -> dict[str, float]:
    """The best and median time of each pass (s) and the list's entries, in this process's
    impactsph."""
    import numpy as np

    sys.path.insert(0, str(HERE.parent / "validation"))
    import beam

    from impactsph import Simulation
    from impactsph.integrate import stable_time_step
    from impactsph.physics import total_lagrangian as tl

    times: dict[str, list[float]] = {name: [] for name in TIMED}
    originals = {name: getattr(tl, name) for name in TIMED}
    for name, function in originals.items():

        def timed(*args, _function=function, _name=name):
            t0 = time.perf_counter()
            _function(*args)
            times[_name].append(time.perf_counter() - t0)
        setattr(tl, name, timed)
    try:
        sim = Simulation(beam.beam_case(depth, ["formulation=total_lagrangian"], 1.0))
        s = sim.state
        free = ~s.clamped
        s.velocity[free, 1] = beam.TIP_SPEED * beam.mode_shape(
            np.clip(s.position[free, 0], 0.0, None))
        dt = 0.5 * stable_time_step(s, sim.problem.table, 0.3)  # within the run's own step
        for _ in range(3):  # compiles
            sim.integrator.step(s, dt)
        for values in times.values():
            values.clear()
        for _ in range(steps):
            sim.integrator.step(s, dt)
    finally:  # the package as it was (a test calls this in its own process)
        for name, function in originals.items():
            setattr(tl, name, function)
    out = {"particles": float(s.n), "calls_per_step": len(times["force_pass"]) / steps,
           "entries": float(sim.solver.ref.neighbours.shape[0])}
    for name, values in times.items():
        out[name + " best"] = min(values)
        out[name + " median"] = statistics.median(values)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trees", nargs="*", default=[], help="other source trees to compare")
    ap.add_argument("--depth", type=int, nargs="+", default=[10])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.depth[0], args.steps)))
        return 0
    from _trees import alternated

    trees = [HERE.parent] + [Path(t).resolve() for t in args.trees]
    results = alternated(__file__, trees, args.depth,
                         lambda depth: ["--depth", str(depth), "--steps", str(args.steps)],
                         args.rounds, args.threads)
    print(f"{args.threads} thread(s), {args.steps} steps a process, us per call (a column "
          f"per round; trees separated by |)")
    for depth in args.depth:
        here = results[(str(trees[0]), depth)]
        print(f"depth {depth}: {here[0]['particles']:.0f} particles, "
              f"{here[0]['entries']:.0f} list entries")
        for key in sorted(k for k in here[0] if k.endswith(("best", "median"))):
            row = [f"  {key:<24}"]
            for tree in trees:
                row.append(" ".join(f"{r[key] * 1e6:8.1f}" for r in results[(str(tree), depth)]))
            if len(trees) > 1:
                ratio = (min(r[key] for r in here)
                         / min(r[key] for r in results[(str(trees[1]), depth)]))
                row.append(f"here / {trees[1].name}: {ratio:.2f}")
            print(" | ".join(row))
        best = min(r["force_pass best"] for r in here)
        print(f"  force pass, here: {here[0]['entries'] / best:.3g} pair evaluations/s")
    print("columns: " + " | ".join(str(t) for t in trees))
    return 0


if __name__ == "__main__":
    sys.exit(main())
