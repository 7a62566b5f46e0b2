"""Cost of the acceleration correction: time per step with AV and with AC, same lattice, same
run, and the ratio (the paper calls the extra time negligible); likewise any other viscosity
scheme against AV (``--schemes ac reconstruction balsara``).

    .venv/bin/python benchmarks/bench_ac_cost.py [--n 1e5] [--repeat 5] [--schemes ac ...]

For each dimension, a lattice of about N particles (dx = 1 mm, h = 1.2 dx, elastic steel) with
random velocities of about 1 m/s (so that the viscosity is active everywhere) is stepped with
each scheme; the best of ``--repeat`` steps is kept.
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
            "output": {"figures": False}}


def step_time(dim: int, n: int, scheme: str, repeat: int) -> tuple[float, int, float]:
    sim = Simulation(validate_case(lattice_case(dim, n, scheme)))
    sim.state.velocity[:] = np.random.default_rng(1).normal(size=sim.state.velocity.shape)
    dt = 0.1 * stable_time_step(sim.state, sim.problem.table, 0.3)
    sim.integrator.step(sim.state, dt)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        sim.integrator.step(sim.state, dt)
        best = min(best, time.perf_counter() - t0)
    pairs = int(sim.solver.buffers.pair_count[: sim.state.n].sum())
    return best, sim.state.n, 2 * pairs / best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=float, default=1e5)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--dims", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--schemes", nargs="+", default=["ac"],
                    help="viscosity schemes timed against av (default: ac)")
    args = ap.parse_args()
    head = "".join(f" {s[:10] + ' s':>12} {s[:10] + '/AV':>13}" for s in args.schemes)
    print(f"{'dim':>3} {'N':>8} {'AV step s':>10}{head} {'AV pairs/s':>11}")
    for dim in args.dims:
        t_av, n, rate = step_time(dim, int(args.n), "av", args.repeat)
        cols = ""
        for scheme in args.schemes:
            t_s, _, _ = step_time(dim, int(args.n), scheme, args.repeat)
            cols += f" {t_s:>12.4g} {t_s / t_av:>13.3f}"
        print(f"{dim:>3} {n:>8} {t_av:>10.4g}{cols} {rate:>11.3g}")
    print("each scheme's step time over AV's: the extra passes' share (AC: the correction; "
          "reconstruction: the velocity gradients).")

if __name__ == "__main__":
    main()
