"""What a second thread costs the first on this machine: a step's kernels run alone and two
at once (issue 16: the small runs' two-thread targets).

A case is run some steps on two threads; its integrator stage's inputs (a corrector stage,
which reads the step's start and so gives the same result at every call) and its pair pass's
inputs are captured.  Each kernel is then timed, best of ``--rounds`` rounds of ``--calls``
calls:

* *alone*: its first share of two, on one thread, nothing else running;
* *two at once, own copies*: its two shares on two Python threads at the same time (the
  passes are compiled ``nogil``), the second share on copies of every array, so that the two
  threads share no cache line and no array;
* *two at once, the same arrays*: the same, both shares on the run's own arrays;
* *numba's threads*: the kernel as a run calls it (``run_chunked`` with two shares), and with
  one share;
* the same for a *control*: a loop of divisions and square roots on a few kilobytes of its
  own, the machine's own figure, with no impactsph code in it.

``slowdown`` is a share's time two at once over its time alone: 1.0 where the two vCPUs are
two cores' worth, up to 2.0 where they share one core's units (two hyperthreads of one core on
the host, which a VM's ``lscpu`` does not show).

    .venv/bin/python benchmarks/bench_concurrency.py taylor cantilever
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from collections.abc import Callable
from typing import Any

import numba as nb
import numpy as np


@nb.njit(nogil=True, cache=True)
def control_share(first, step, values, out):  # pragma: no cover (compiled)
    """Share ``first`` of ``step``: 200 rounds of a division and a square root per value."""
    n = values.shape[0]
    for i in range(first * n // step, (first + 1) * n // step):
        acc = values[i]
        for _ in range(200):
            acc = np.sqrt(acc + 1.0) / (acc + 0.5)
        out[i] = acc


def capture(case_name: str, steps: int) -> dict[str, tuple[Callable[..., Any], tuple]]:
    """The case after ``steps`` steps on two threads: its stage's and its pair pass's
    chunked pass and arguments (copies, the shares' ``first, step`` left out)."""
    import impactsph.integrate as integrate_module
    import impactsph.physics.rates as rates_module
    from impactsph import Simulation, load_case

    nb.set_num_threads(2)
    sim = Simulation(load_case(case_name, ["time.end=1", "compute.threads=2",
                                           "output.figures=false"]))
    for _ in range(steps):
        sim.integrator.step(sim.state, sim._survey().dt)
    taken: dict[str, tuple[Callable[..., Any], tuple]] = {}

    def copied(arguments: tuple) -> tuple:
        return tuple(a.copy() if isinstance(a, np.ndarray) else a for a in arguments)

    run_stage, run_chunked = integrate_module.run_stage, rates_module.run_chunked

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


def two_at_once(kernel: Callable[..., Any], first_args: tuple, second_args: tuple,
                calls: int, rounds: int) -> float:
    """The fastest round's microseconds a call of share 0 of 2 (on ``first_args``) while
    share 1 (on ``second_args``) runs on another Python thread, the two started together."""
    best = float("inf")
    for _ in range(rounds):
        gate = threading.Barrier(2)
        spent = [0.0, 0.0]

        def loop(share: int, arguments: tuple, gate: threading.Barrier,
                 spent: list[float]) -> None:
            gate.wait()
            start = time.perf_counter()
            for _ in range(calls):
                kernel(share, 2, *arguments)
            spent[share] = time.perf_counter() - start

        workers = [threading.Thread(target=loop, args=(0, first_args, gate, spent)),
                   threading.Thread(target=loop, args=(1, second_args, gate, spent))]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        best = min(best, spent[0] / calls)
    return 1e6 * best


def measure_kernel(name: str, kernel: Callable[..., Any], arguments: tuple, calls: int,
                   rounds: int) -> dict[str, Any]:
    """One kernel's times (us a call) alone, two at once and on numba's threads."""
    from impactsph.physics.chunked import run_chunked

    own = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in arguments)
    kernel(0, 2, *arguments)  # (loaded or compiled)
    alone = best_per_call(lambda: kernel(0, 2, *arguments), calls, rounds)
    copies = two_at_once(kernel, arguments, own, calls, rounds)
    same = two_at_once(kernel, arguments, arguments, calls, rounds)
    numba_two = best_per_call(lambda: run_chunked(kernel, 2, *arguments), calls, rounds)
    numba_one = best_per_call(lambda: run_chunked(kernel, 1, *arguments), calls, rounds)
    return {"kernel": name, "alone": alone, "two at once, own copies": copies,
            "two at once, same arrays": same, "numba, 2 threads": numba_two,
            "numba, 1 thread": numba_one, "slowdown": copies / alone,
            "speedup": numba_one / numba_two}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="*", default=["taylor", "cantilever"])
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", help="write every number here")
    args = parser.parse_args(argv)
    rows = []
    values = np.linspace(0.5, 2.0, 2048)
    rows.append({"case": "control", **measure_kernel(
        "divisions and roots", control_share, (values, np.zeros_like(values)), args.calls,
        args.rounds)})
    for case_name in args.cases:
        for name, (kernel, arguments) in capture(case_name, args.steps).items():
            rows.append({"case": case_name, **measure_kernel(name, kernel, arguments,
                                                             args.calls, args.rounds)})
    print(f"{'case':12s} {'kernel':20s} {'alone':>8s} {'own copies':>11s} {'same':>8s} "
          f"{'slowdown':>9s} {'numba 1':>8s} {'numba 2':>8s} {'speedup':>8s}   (us a call)")
    for r in rows:
        print(f"{r['case']:12s} {r['kernel']:20s} {r['alone']:8.1f} "
              f"{r['two at once, own copies']:11.1f} {r['two at once, same arrays']:8.1f} "
              f"{r['slowdown']:9.2f} {r['numba, 1 thread']:8.1f} {r['numba, 2 threads']:8.1f} "
              f"{r['speedup']:8.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "argv": argv}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
