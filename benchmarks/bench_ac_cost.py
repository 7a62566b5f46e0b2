"""Cost of the acceleration correction: time per step with AV and with AC, same lattice, same
run, and the ratio (the paper calls the extra time negligible); likewise any other viscosity
scheme against AV (``--schemes ac reconstruction balsara``).

    .venv/bin/python benchmarks/bench_ac_cost.py [--n 1e5] [--repeat 5] [--schemes ac ...]

For each dimension, a lattice of about N particles (dx = 1 mm, h = 1.2 dx, elastic steel, no
stabilisation: the paper's scheme) with random velocities of about 1 m/s (so that the
viscosity is active everywhere) is stepped with each scheme, the schemes' runs side by side
in one process and stepped in turn; the best of ``--repeat`` steps is kept.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from impactsph.integrate import stable_time_step
from impactsph.loading import validate_case
from impactsph.simulation import Simulation


def lattice_case(dim: int, n: int, scheme: str) -> dict:
    side = max(1, round(n ** (1.0 / dim)))
    dx = 1e-3
    return {"name": f"ac{dim}", "dimension": dim,
            "materials": {"m": {"model": "elastic", "density": 7850.0, "youngs_modulus": 2e11}},
            "bodies": [{"name": "b", "material": "m", "velocity": [0.0] * dim,
                        "geometry": {"origin": [0.0] * dim, "size": [side * dx] * dim,
                                     "spacing": dx}}],
            "viscosity": {"scheme": scheme}, "time": {"end": 1.0},
            # the width the recorded numbers were taken at (the default became 1.3 dx on
            # 2026-12-03)
            "kernel": {"h_over_dx": 1.2},
            # the paper's scheme alone: "auto" would add the kernel gradient correction and
            # the hourglass control for this elastic material (since issue 11), whose passes
            # would then be part of every step timed
            "stabilisation": {"gradient_correction": "none", "hourglass": 0.0},
            "output": {"figures": False}}


def alternated(dim: int, n: int, schemes: list[str], repeat: int
               ) -> tuple[dict[str, float], int, float]:
    """Best step time (s) of each scheme, the schemes' runs built side by side in this
    process and stepped in turn, ``repeat`` rounds (a busy spell falls on all of them);
    the particle count and AV's pair evaluations per second (the first scheme's)."""
    sims = {}
    for scheme in schemes:
        sim = Simulation(validate_case(lattice_case(dim, n, scheme)))
        sim.state.velocity[:] = np.random.default_rng(1).normal(size=sim.state.velocity.shape)
        dt = 0.1 * stable_time_step(sim.state, sim.problem.table, 0.3)
        sim.integrator.step(sim.state, dt)  # compiles
        sims[scheme] = (sim, dt)
    best = dict.fromkeys(schemes, np.inf)
    for _ in range(repeat):
        for scheme, (sim, dt) in sims.items():
            t0 = time.perf_counter()
            sim.integrator.step(sim.state, dt)
            best[scheme] = min(best[scheme], time.perf_counter() - t0)
    sim = sims[schemes[0]][0]
    pairs = int(sim.solver.buffers.pair_count[: sim.state.n].sum())
    return best, sim.state.n, 2 * pairs / best[schemes[0]]


def main() -> None:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--n", type=float, default=1e5)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--dims", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--schemes", nargs="+", default=["ac"],
                    help="viscosity schemes timed against av (default: ac)")
    args = ap.parse_args()
    head = "".join(f" {s[:10] + ' s':>12} {s[:10] + '/AV':>13}" for s in args.schemes)
    print(f"{'dim':>3} {'N':>8} {'AV step s':>10}{head} {'AV pairs/s':>11}")
    for dim in args.dims:
        best, n, rate = alternated(dim, int(args.n), ["av", *args.schemes], args.repeat)
        t_av = best["av"]
        cols = "".join(f" {best[s]:>12.4g} {best[s] / t_av:>13.3f}" for s in args.schemes)
        print(f"{dim:>3} {n:>8} {t_av:>10.4g}{cols} {rate:>11.3g}")
    print("each scheme's step time over AV's: the extra passes' share (AC: the correction; "
          "reconstruction: the velocity gradients).")

if __name__ == "__main__":
    main()
