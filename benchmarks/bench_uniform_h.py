"""The pair pass of a run's own passes module against the module of its neighbour loops where
every smoothing length is the same (``PassOptions.uniform_h``, ``CpuRates.neighbour_loops``),
in one process, on the same captured inputs, alternated round by round; checks that both give
the same results to the bit.

    .venv/bin/python benchmarks/bench_uniform_h.py [--inputs 2d 3d taylor cantilever]
        [--n 1e5] [--rounds 6]

``2d`` and ``3d`` are ``bench_rates.py``'s lattices (the paper's scheme, AV, h = 1.2 dx);
``taylor`` and ``cantilever`` the built-in cases after 2 us of their run.  Prints the best of
each round in ms and the ratios (best over best, and the median of the rounds' ratios).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _simulation(name: str, n: int):
    from impactsph import Simulation, load_case
    from impactsph.loading import validate_case

    if name in ("2d", "3d"):
        sys.path.insert(0, str(HERE))
        from bench_rates import make_case

        sim = Simulation(validate_case(make_case(n, int(name[0]))))
        sim.state.velocity[:] = np.random.default_rng(1).normal(size=sim.state.velocity.shape)
        return sim
    sim = Simulation(load_case(name, ["output.figures=false"]))
    sim.run(2e-6)
    return sim


def measure(name: str, n: int, rounds: int) -> dict:
    """Best times (s) of the two modules' pair pass, round by round, and whether their
    outputs are the same to the bit."""
    sim = _simulation(name, n)
    backend = sim.solver.backend
    own, uniform = backend.passes, backend.neighbour_loops(True)
    captured = {}
    pair_pass = uniform.pair_pass

    def capture(*args):
        if args[0] == 0:  # the first thread's call, as one call over every chunk
            captured["args"] = [0, 1, *(a.copy() if isinstance(a, np.ndarray) else a
                                        for a in args[2:])]
        return pair_pass(*args)

    uniform.pair_pass = capture
    sim.solver.rates(sim.state)
    uniform.pair_pass = pair_pass
    args = captured["args"]
    outputs = {}
    for label, module in (("own", own), ("uniform", uniform)):
        run = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
        module.pair_pass(*run)
        outputs[label] = [a for a in run if isinstance(a, np.ndarray)]
    same = all(a.tobytes() == b.tobytes() for a, b in zip(*outputs.values(), strict=True))
    calls = max(5, int(2e5 // max(sim.state.n, 1)))  # some 0.2 s a round at every size
    times: dict[str, list[float]] = {"own": [], "uniform": []}
    for _ in range(rounds):
        for label, module in (("own", own), ("uniform", uniform)):
            best = np.inf
            for _ in range(calls):
                t0 = time.perf_counter()
                module.pair_pass(*args)
                best = min(best, time.perf_counter() - t0)
            times[label].append(best)
    return {"particles": sim.state.n, "same_bits": same, **times}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", nargs="+", default=["2d", "3d", "taylor", "cantilever"],
                    choices=["2d", "3d", "taylor", "cantilever"])
    ap.add_argument("--n", type=float, default=1e5, help="the lattices' particle count")
    ap.add_argument("--rounds", type=int, default=6)
    args = ap.parse_args()
    import numba

    print(f"{numba.get_num_threads()} thread(s); the pair pass, best of each round, ms")
    for name in args.inputs:
        r = measure(name, int(args.n), args.rounds)
        own, uniform = np.array(r["own"]), np.array(r["uniform"])
        print(f"{name} ({r['particles']} particles), same bits: {r['same_bits']}")
        print("  own     " + " ".join(f"{t * 1e3:8.3f}" for t in own))
        print("  uniform " + " ".join(f"{t * 1e3:8.3f}" for t in uniform))
        print(f"  uniform / own: best {uniform.min() / own.min():.3f}, "
              f"median of the rounds {np.median(uniform / own):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
