"""The neighbour list's rebuild in one sweep against count-then-store (issue 16).

A case is run some steps (its list rebuilt as the run rebuilds it), then its list is built
again from the same rows, alternately without the offsets of the list it replaces (two
sweeps: a count, then a store) and with them (one sweep, each share of rows stored in a room
sized from them: ``NeighbourList.build``'s ``like``), round after round in one process; the
two lists are checked equal to the bit, and each way's fastest, first quartile and median
build printed in microseconds.

    .venv/bin/python benchmarks/bench_list_build.py taylor cantilever --threads 1 2
    .venv/bin/python benchmarks/bench_list_build.py taylor3d --threads 1 2 --steps 100 --rounds 12
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

FIELDS = ("order", "offsets", "indices", "inner_ends", "splits")


def measure(case_name: str, threads: int, steps: int, rounds: int) -> dict:
    """The case after ``steps`` steps on ``threads`` threads, its list built ``rounds``
    times each way, alternated."""
    import numba

    from impactsph import Simulation, load_case
    from impactsph.kernels import SUPPORT_RADIUS
    from impactsph.neighbours import NeighbourList

    numba.set_num_threads(threads)
    sim = Simulation(load_case(case_name, ["time.end=1", f"compute.threads={threads}"]))
    for _ in range(steps):
        sim.integrator.step(sim.state, sim._survey().dt)
    solver, state = sim.solver, sim.state
    rows = solver._ext["x"] if solver._ext is not None else state.position
    h = state.smoothing_length
    support = SUPPORT_RADIUS * float(h.max())
    skin = solver.skin_fraction * support
    varied = solver.max_stretch > 1.0 or h.max() > h.min()
    h_rows = solver._row_smoothing_lengths(state) if varied else None
    last = solver.neighbours
    like = last.offsets
    times: dict[str, list[float]] = {"two sweeps": [], "one sweep": []}
    built = {}
    for _ in range(rounds):
        for way in times:
            start = time.perf_counter()
            built[way] = NeighbourList.build(rows, support, skin, last.inner_reach, h_rows,
                                             like if way == "one sweep" else None)
            times[way].append(time.perf_counter() - start)
    two, one = built["two sweeps"], built["one sweep"]
    same = all((getattr(two, f) is None and getattr(one, f) is None)
               or np.array_equal(getattr(two, f), getattr(one, f)) for f in FIELDS)
    result = {"case": case_name, "threads": threads, "rows": int(rows.shape[0]),
              "entries": int(two.offsets[-1]), "sweeps": [two.sweeps, one.sweeps],
              "same": bool(same)}
    for way, values in times.items():
        us = np.array(values) * 1e6
        result[way] = {"min": float(us.min()), "q25": float(np.percentile(us, 25)),
                       "median": float(np.median(us))}
    result["ratio of medians"] = result["one sweep"]["median"] / result["two sweeps"]["median"]
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("cases", nargs="*", default=["taylor", "cantilever"])
    ap.add_argument("--threads", nargs="+", type=int, default=[1])
    ap.add_argument("--steps", type=int, default=300, help="steps before the builds")
    ap.add_argument("--rounds", type=int, default=200)
    ap.add_argument("--json", help="write every number here")
    args = ap.parse_args(argv)
    results = []
    for name in args.cases:
        for threads in args.threads:
            r = measure(name, threads, args.steps, args.rounds)
            results.append(r)
            two, one = r["two sweeps"], r["one sweep"]
            print(f"{name:12s} {threads} thread(s) {r['rows']:7d} rows {r['entries']:9d} "
                  f"entries: two sweeps {two['median']:10.1f} us (min {two['min']:.1f}), one "
                  f"{one['median']:10.1f} us (min {one['min']:.1f}): "
                  f"{r['ratio of medians']:.3f}; sweeps {r['sweeps']}, "
                  f"{'same lists' if r['same'] else 'LISTS DIFFER'}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0 if all(r["same"] for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
