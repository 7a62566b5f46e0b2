"""Cost of the stabilisation options (docs/stabilisation.md): one rate evaluation of a lattice
of about 1e5 particles in 2D and 3D (the ``bench_rates.py`` case: elastic steel, small random
velocities), plain, with the kernel gradient correction, and with the correction and the
hourglass control.  The three set-ups are timed in turn, round after round, and the best time
of each is kept, so that all three see the same machine.

Usage::

    python benchmarks/bench_stabilisation.py [--size 1e5] [--rounds 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_rates import make_case  # noqa: E402

from impactsph import Simulation  # noqa: E402
from impactsph.loading import validate_case  # noqa: E402

#: each set-up names both options: left out, they are "auto", which for this elastic lattice
#: resolves to the correction of the velocity gradient and forces and the hourglass control
#: (so "plain" timed the defaults' stabilisation until 2026-12-03)
OPTIONS = {
    "plain": {"gradient_correction": "none", "hourglass": 0.0},
    "gradient correction": {"gradient_correction": "velocity_gradient", "hourglass": 0.0},
    "correction + hourglass": {"gradient_correction": "velocity_gradient", "hourglass": 1.0},
}


def setup(n: int, dim: int, options: dict) -> Simulation:
    case = make_case(n, dim)
    case["stabilisation"] = options
    sim = Simulation(validate_case(case))
    sim.state.velocity[:] = np.random.default_rng(1).normal(0.0, 1.0, sim.state.velocity.shape)
    sim.solver.rates(sim.state)  # warm
    return sim


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=1e5)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    for dim in (2, 3):
        sims = {name: setup(int(args.size), dim, opts) for name, opts in OPTIONS.items()}
        best = dict.fromkeys(sims, np.inf)
        for _ in range(args.rounds):
            for name, sim in sims.items():
                t0 = time.perf_counter()
                sim.solver.rates(sim.state)
                best[name] = min(best[name], time.perf_counter() - t0)
        base = best["plain"]
        print(f"{dim}D, {sims['plain'].state.n} particles: " + "; ".join(
            f"{name} {t * 1e3:.1f} ms ({t / base:.2f}x)" for name, t in best.items()),
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
