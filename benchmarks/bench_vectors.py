"""How the compiled loops use the vectors (``$IMPACTSPH_VECTORS``, :mod:`impactsph.vectors`):
each choice in a process of its own (numba fixes its features for a process), alternated
round by round, with every time divided by a reference timed in the same process. The
choices: ``host`` (LLVM's own for the CPU), ``256`` (256-bit vectors alone: the host's
features and ``+prefer-256-bit``), ``tuned`` (impactsph's default for the CPU) and
``no-gather`` (256-bit vectors and loads for gathers on any CPU: ``+prefer-256-bit`` and
``+prefer-no-gather``, what ``tuned`` makes on a Zen 4, to measure it elsewhere).

The reference is the naive yardstick (``../shared/bench/naive_pairs.py``, loaded as
``bench_bare_loop.py`` loads it: its cell list and 2D rate sums on the same 1e5 lattice),
whose time neither choice moves (42.9-44.8 ms on two threads of a Zen 4 under each,
2026-12-06; ``bench_bare_loop.py``'s bare loop, which gathers, is 0.8 of itself without
gathers there; where that file is missing, a chain of square roots and divisions, scalar):
a process that runs in a slower minute of the machine runs its reference slower too, so
the ratios compare the choices where the raw times, a process apart, spread by 10-40% on
the project's 2-vCPU machines. Timed in each process, best of
``--rounds`` after a warm-up: one rate evaluation of ``bench_rates.py``'s 2D and 3D lattices
(1e5 particles, random velocities), and whole runs of the paper's Taylor bar and of the
cantilever's first ``--cantilever-end`` seconds.

    .venv/bin/python benchmarks/bench_vectors.py --threads 1 2 --rounds 3 --processes 3

prints, for each thread count, each item's ratio to the reference under each choice (the
best of the processes) and each choice's quotient by the first (< 1: faster than LLVM's).
``--item`` runs one process's measurement and prints it as JSON (what the alternation
calls)."""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np

import impactsph  # noqa: F401  (first: the width is chosen when impactsph is imported)

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_bare_loop  # noqa: E402  (a script beside this one)

CHOICES = ("host", "256", "tuned", "no-gather")
ITEMS = ("rates 2D", "rates 3D", "taylor", "cantilever")


def _best(function, rounds: int) -> float:
    function()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def measure(threads: int, rounds: int, side: int, cantilever_end: float,
            items: tuple[str, ...] = ITEMS) -> dict:
    """One process's measurement: the reference's seconds and each item's time over it."""
    sys.path.insert(0, str(HERE))
    from bench_rates import make_case

    from impactsph import Simulation, load_case
    from impactsph.loading import validate_case
    from impactsph.vectors import cpu_name, vector_width

    numba.set_num_threads(threads)
    reference_name, reference = _reference(side)

    timed = {}
    for dim in (2, 3):
        if f"rates {dim}D" in items:
            sim = Simulation(validate_case(make_case(side * side, dim)))
            sim.state.velocity[:] = np.random.default_rng(1).normal(
                0.0, 1.0, size=sim.state.velocity.shape)
            timed[f"rates {dim}D"] = (lambda s=sim: s.solver.rates(s.state))
    runs = {"taylor": [], "cantilever": [f"time.end={cantilever_end!r}"]}
    for name, overrides in runs.items():
        if name in items:
            case = load_case(name, ["output.figures=false", f"compute.threads={threads}",
                                    *overrides])
            Simulation(case).run(t_end=1e-2 * case.time.end)  # compiled (or loaded) first
            timed[name] = (lambda c=case: Simulation(c).run())
    seconds = _best(reference, 3 * rounds)
    ratios = {name: _best(function, rounds) / seconds for name, function in timed.items()}
    return {"vectors": vector_width(), "cpu": cpu_name(), "threads": threads,
            "reference": reference_name, "reference seconds": seconds, "ratios": ratios}


@numba.njit(parallel=True)  # (not cached: numba caches a script's functions under its name)
def _chain(values, out):  # pragma: no cover (compiled)
    """200 rounds of a square root and a division on each value: scalar, no vectors."""
    for i in numba.prange(values.shape[0]):
        acc = values[i]
        for _ in range(200):
            acc = math.sqrt(acc + 1.0) / (acc + 0.5)
        out[i] = acc


def _reference(side: int) -> tuple[str, Callable[[], None]]:
    """The reference kernel: the naive yardstick on the ``side``^2 lattice, where its file
    is (``../shared/bench/naive_pairs.py``), else a chain of roots and divisions on as many
    values as the lattice has particles, a tenth (scalar code, which no choice moves)."""
    fields, h = bench_bare_loop.lattice(side)
    if not bench_bare_loop.NAIVE.is_file():
        values = fields["x"][: max(1, fields["x"].size // 10)].copy()
        out = np.empty_like(values)
        return "roots and divisions", lambda: _chain(values, out)
    columns = tuple(fields[k] for k in ("x", "y", "vx", "vy", "rho", "m", "p", "sxx", "sxy",
                                        "syy", "c"))
    naive = bench_bare_loop.load_naive(bench_bare_loop.NAIVE)
    reach = 2.0 * h
    cells = int((1 + 2 * reach) / reach) + 2
    sums = [np.empty(fields["x"].size) for _ in range(bench_bare_loop.SUMS)]

    def run_naive() -> None:
        order, start, cell = naive.build_cells(fields["x"], fields["y"], reach, -reach,
                                               -reach, cells, cells)
        naive.rates(*columns, h, order, start, cell, cells, cells, *sums)
    return "naive yardstick", run_naive


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=3, help="timings an item, best kept")
    ap.add_argument("--processes", type=int, default=3, help="processes a choice, alternated")
    ap.add_argument("--side", type=int, default=316, help="lattice side (316: 1e5 particles)")
    ap.add_argument("--cantilever-end", type=float, default=4e-4)
    ap.add_argument("--items", nargs="+", choices=ITEMS, default=list(ITEMS))
    ap.add_argument("--choices", nargs="+", choices=CHOICES, default=list(CHOICES))
    ap.add_argument("--item", action="store_true", help="one process's measurement, as JSON")
    ap.add_argument("--json", type=Path, help="write every number here")
    args = ap.parse_args(argv)
    if args.item:
        print(json.dumps(measure(args.threads[0], args.rounds, args.side,
                                 args.cantilever_end, tuple(args.items))))
        return 0
    from impactsph.vectors import (
        FEATURES_VARIABLE,
        NO_GATHER,
        PREFER_256,
        VECTORS_VARIABLE,
        _host_features,
    )

    rows = []
    for process in range(args.processes):
        for threads in args.threads:
            for choice in args.choices:
                env = {k: v for k, v in os.environ.items() if k != FEATURES_VARIABLE}
                if choice == "256":
                    env[FEATURES_VARIABLE] = f"{_host_features()},{PREFER_256}"
                elif choice == "no-gather":
                    env[FEATURES_VARIABLE] = f"{_host_features()},{PREFER_256},{NO_GATHER}"
                else:
                    env[VECTORS_VARIABLE] = choice
                command = [sys.executable, __file__, "--item", "--threads", str(threads),
                           "--rounds", str(args.rounds), "--side", str(args.side),
                           "--cantilever-end", repr(args.cantilever_end),
                           "--items", *args.items]
                done = subprocess.run(command, env=env, capture_output=True, text=True)
                if done.returncode != 0:
                    sys.stderr.write(done.stderr)
                    return done.returncode
                row = json.loads(done.stdout.strip().splitlines()[-1])
                row.update(choice=choice, process=process)
                rows.append(row)
                print(f"process {process}, {threads} thread(s), {choice:4s} "
                      f"({row['vectors']}): reference {row['reference seconds'] * 1e3:.2f} "
                      "ms; " + ", ".join(f"{k} {v:.3f}" for k, v in row["ratios"].items()),
                      flush=True)
    print(f"\n{platform.processor() or platform.machine()}, {rows[0]['cpu']}: each item's "
          "time over the reference's in its process, best of the processes")
    first = args.choices[0]
    print(f"{'threads':>7s} {'item':12s} " + " ".join(f"{c:>8s}" for c in args.choices) + " "
          + " ".join(f"{c + ' / ' + first:>14s}" for c in args.choices[1:]))
    for threads in args.threads:
        for item in args.items:
            best = {choice: min(r["ratios"][item] for r in rows
                                if r["threads"] == threads and r["choice"] == choice)
                    for choice in args.choices}
            print(f"{threads:7d} {item:12s} " + " ".join(f"{best[c]:8.3f}" for c in args.choices)
                  + " " + " ".join(f"{best[c] / best[first]:14.3f}" for c in args.choices[1:]))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "argv": sys.argv[1:]}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
