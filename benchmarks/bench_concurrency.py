"""What a second thread costs the first on this machine: a step's kernels on numba's two
threads, one share at a time and both at once (issue 16: the small runs' two-thread targets).

A case is run some steps on two threads; its integrator stage's inputs (a corrector stage,
which reads the step's start and so gives the same result at every call) and its pair pass's
inputs are captured.  Each kernel is then timed on numba's threads, as a run calls it
(:func:`impactsph.physics.chunked.run_chunked`'s drive: a parallel region of two shares),
best of ``--rounds`` rounds of ``--calls`` calls and the median call:

* *share 0 alone*: the region runs its first share (on the calling thread) and not the
  second (the other thread waits at the region's end);
* *share 1 alone*: the second share only (on numba's worker thread; the caller waits);
* *both*: the region as a run has it;
* *one thread*: the whole pass in one share;

and the same for a *control*, a loop of square roots and divisions on a few kilobytes of its
own (no impactsph code in it).  Where the two vCPUs are two cores, *both* takes about the
longer share plus a few microseconds for the region; where they share one core's units,
about the two shares' sum.

    .venv/bin/python benchmarks/bench_concurrency.py taylor cantilever
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from typing import Any

import numba as nb
import numpy as np

import impactsph  # noqa: F401 (its threading settings before numba's threads start)
from impactsph.physics.chunked import _address, _call_at, run_chunked


@nb.njit(nogil=True)  # (not cached: numba caches a script's functions under its name)
def control_share(first, step, values, out):  # pragma: no cover (compiled)
    """Share ``first`` of ``step``: 200 rounds of a division and a square root per value."""
    n = values.shape[0]
    for i in range(first * n // step, (first + 1) * n // step):
        acc = values[i]
        for _ in range(200):
            acc = np.sqrt(acc + 1.0) / (acc + 0.5)
        out[i] = acc


def two_threads() -> int:
    """Two, or the one thread numba has (``NUMBA_NUM_THREADS=1``: the regions then run their
    shares one after the other)."""
    return min(2, nb.config.NUMBA_NUM_THREADS)


def capture(case_name: str, steps: int) -> dict[str, tuple[Callable[..., Any], tuple]]:
    """The case after ``steps`` steps on two threads: its stage's and its pair pass's
    chunked pass and arguments (copies, the shares' ``first, step`` left out)."""
    import impactsph.integrate as integrate_module
    import impactsph.physics.rates as rates_module
    from impactsph import Simulation, load_case

    threads = two_threads()
    nb.set_num_threads(threads)
    sim = Simulation(load_case(case_name, ["time.end=1", f"compute.threads={threads}",
                                           "output.figures=false"]))
    for _ in range(steps):
        sim.integrator.step(sim.state, sim._survey().dt)
    taken: dict[str, tuple[Callable[..., Any], tuple]] = {}

    def copied(arguments: tuple) -> tuple:
        return tuple(a.copy() if isinstance(a, np.ndarray) else a for a in arguments)

    run_stage = integrate_module.run_stage

    def stage(stage_pass, threaded, n_active, *arguments):
        taken["stage"] = (stage_pass, (n_active, *copied(arguments)))  # the last: a corrector
        return run_stage(stage_pass, threaded, n_active, *arguments)

    def chunked(chunk_pass, threads, *arguments):
        if chunk_pass.__name__ == "pair_pass":
            taken.setdefault("pair pass", (chunk_pass, copied(arguments)))
        return run_chunked(chunk_pass, threads, *arguments)

    integrate_module.run_stage, rates_module.run_chunked = stage, chunked
    try:
        sim.integrator.step(sim.state, sim._survey().dt)
    finally:
        integrate_module.run_stage, rates_module.run_chunked = run_stage, run_chunked
    return taken


def best_per_call(call: Callable[[], None], calls: int, rounds: int) -> float:
    """The fastest round's microseconds a call."""
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        best = min(best, (time.perf_counter() - start) / calls)
    return 1e6 * best


@nb.njit(parallel=True)
def drive_some(address, run, flat):  # pragma: no cover (compiled)
    """The chunked pass at ``address`` for the shares ``t`` of two where ``run[t]``, in one
    parallel region on numba's threads (as :func:`impactsph.physics.chunked._drive`)."""
    for t in nb.prange(2):
        if run[t]:
            _call_at(address, t, 2, flat)


def median_per_call(call: Callable[[], None], calls: int) -> float:
    """The median call's microseconds."""
    spent = np.empty(calls)
    for k in range(calls):
        start = time.perf_counter()
        call()
        spent[k] = time.perf_counter() - start
    return 1e6 * float(np.median(spent))


def measure_kernel(name: str, kernel: Callable[..., Any], arguments: tuple, calls: int,
                   rounds: int) -> dict[str, Any]:
    """One kernel's times (us a call, best round's mean and median call) with each share
    alone, both and one thread, on numba's threads."""
    nb.set_num_threads(two_threads())
    address, _, flat = _address(kernel, arguments)
    row: dict[str, Any] = {"kernel": name}
    for label, run in (("share 0 alone", (True, False)), ("share 1 alone", (False, True)),
                       ("both", (True, True))):
        mask = np.array(run)

        def call(mask: np.ndarray = mask) -> None:
            drive_some(address, mask, flat)

        call()  # (compiled)
        row[label] = best_per_call(call, calls, rounds)
        row[f"{label}, median"] = median_per_call(call, calls)
    nb.set_num_threads(1)
    row["one thread"] = best_per_call(lambda: run_chunked(kernel, 1, *arguments), calls,
                                      rounds)
    nb.set_num_threads(two_threads())
    row["speedup"] = row["one thread"] / row["both"]
    row["both over the longer share"] = row["both"] / max(row["share 0 alone"],
                                                          row["share 1 alone"])
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="*", default=["taylor", "cantilever"])
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", help="write every number here")
    args = parser.parse_args(argv)
    rows = []
    values = np.linspace(0.5, 2.0, 48)  # about 25 us a share: a stage's length
    rows.append({"case": "control", **measure_kernel(
        "roots, divisions", control_share, (values, np.zeros_like(values)), args.calls,
        args.rounds)})
    for case_name in args.cases:
        for name, (kernel, arguments) in capture(case_name, args.steps).items():
            rows.append({"case": case_name, **measure_kernel(name, kernel, arguments,
                                                             args.calls, args.rounds)})
    print(f"{'case':12s} {'kernel':14s} {'share 0':>9s} {'share 1':>9s} {'both':>9s} "
          f"{'1 thread':>9s} {'speedup':>8s} {'both/longer':>12s}   (us a call, best round; "
          f"median call in brackets)")
    for r in rows:
        print(f"{r['case']:12s} {r['kernel']:14s} "
              + " ".join(f"{r[k]:6.1f} ({r[k + ', median']:6.1f})"
                         for k in ("share 0 alone", "share 1 alone", "both"))
              + f" {r['one thread']:9.1f} {r['speedup']:8.2f} "
              f"{r['both over the longer share']:12.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "argv": argv}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
