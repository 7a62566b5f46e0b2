"""Milliseconds per step and pair evaluations per second on the GPU and on the CPU, at 1e5,
1e6 and 1e7 particles in 2D and 3D: one command for a machine with a GPU, within a time
budget (issue 16).

Each item (dimension, size, device) runs in a fresh process: the lattice of
``bench_rates.make_case`` (steel-like, dx = 1 mm, h = 1.2 dx, the paper's scheme, small
random velocities so that the viscosity works) with ``compute.device`` set, one warm step
(compilation, the first neighbour build, the first transfers), then ``--steps`` timed steps
of the integrator (two rate evaluations each, the time integration and the neighbour
updates: what a run pays a step, outputs excepted). It prints a Markdown table and writes
``--json``: ms per step, pair evaluations per second (those of the timed steps over their wall
time), the device the passes ran on (a run asked to use a GPU that cannot falls back to the
CPU and says so: the column shows where it ran), the growth of the peak host memory from just
before the lattice is built and, on a GPU, the device memory in use, each per particle.

The items run smallest first; one whose estimated time (the previous size's, scaled by the
particle count) would pass the budget is skipped and listed as such, so the command ends
within ``--budget`` seconds plus one item.

    python benchmarks/bench_gpu.py                        # GPU and CPU, 2D and 3D, 1e5-1e7
    python benchmarks/bench_gpu.py --devices cpu --sizes 1e4 1e5 --budget 60
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def run_item(dim: int, n: int, device: str, steps: int) -> dict:
    """One item, in this process (the child)."""
    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_rates import SEED, current_rss_mib, make_case, peak_rss_mib

    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    def case(size: int) -> dict:
        data = make_case(size, dim)
        data["compute"] = {"device": "cpu" if device == "cpu" else "gpu",
                           "resident": device != "gpu-host"}
        return data

    def stepper(sim: Simulation):
        """One step as a run takes it: the integrator's (or, with the state on the GPU, the
        device's) step and the survey."""
        if sim._resident is not None:
            def step(dt: float) -> None:
                sim._resident.step(sim._state, dt)
                sim._survey()  # one small record back: the stream is synchronised
        else:
            def step(dt: float) -> None:
                sim.integrator.step(sim._state, dt)
                sim._survey()
        return step

    warm = Simulation(validate_case(case(2**dim)))  # the compiled code, the CUDA context
    stepper(warm)(1e-9)
    del warm
    baseline = current_rss_mib()
    data = case(n)
    t0 = time.perf_counter()
    sim = Simulation(validate_case(data))
    setup = time.perf_counter() - t0
    state = sim.state
    state.velocity[:] = np.random.default_rng(SEED).normal(0.0, 1.0, size=state.velocity.shape)
    dt = stable_time_step(state, sim.problem.table, 0.3)
    resident = sim._resident is not None
    if resident:
        sim._resident.upload(state)  # the random velocities
    step = stepper(sim)
    t0 = time.perf_counter()
    step(dt)  # compilation, transfers, the first neighbour update
    warm = time.perf_counter() - t0
    if resident:
        sim._fold()
    pairs0 = sim.solver.pair_evaluations
    t0 = time.perf_counter()
    for _ in range(steps):
        step(dt)
    wall = time.perf_counter() - t0
    if resident:
        sim._fold()
    pairs = sim.solver.pair_evaluations - pairs0
    ran_on = getattr(sim.solver.backend, "device", "cpu")
    row = {"dimension": dim, "n_target": n, "n_particles": state.n, "device_asked": device,
           "device": ran_on, "state_on_device": resident, "steps": steps,
           "setup_seconds": setup,
           "warm_step_seconds": warm, "ms_per_step": 1e3 * wall / steps,
           "pair_evaluations_per_second": pairs / wall,
           "pairs_per_particle": pairs / (2 * steps * state.n),
           "host_bytes_per_particle": (peak_rss_mib() - baseline) * 2**20 / state.n}
    from impactsph.gpu import simulator_enabled

    if ran_on == "gpu" and not simulator_enabled():  # (the simulator: for a smoke test)
        from numba import cuda

        free, total = cuda.current_context().get_memory_info()
        row["gpu_bytes_per_particle"] = (total - free) / state.n
        row["gpu_name"] = cuda.get_current_device().name.decode()
    return row


def child(dim: int, n: int, device: str, steps: int, timeout: float) -> dict:
    """Run one item in a fresh process; its row, or the reason it has none."""
    try:
        out = subprocess.run(
            [sys.executable, __file__, "--child", str(dim), str(n), device, str(steps)],
            capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {"dimension": dim, "n_target": n, "device_asked": device,
                "error": f"timed out after {timeout:.0f} s"}
    if out.returncode != 0:
        tail = (out.stderr.strip().splitlines() or ["no message"])[-1]
        return {"dimension": dim, "n_target": n, "device_asked": device,
                "error": f"exit {out.returncode}: {tail}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--devices", nargs="+", default=["gpu", "gpu-host", "cpu"],
                    choices=["gpu", "gpu-host", "cpu"],
                    help="gpu: the whole step on the GPU where the case allows (this one "
                    "does); gpu-host: the rate passes on the GPU, the state on the host "
                    "(compute.resident = false); cpu")
    ap.add_argument("--dims", nargs="+", type=int, default=[2, 3], choices=[1, 2, 3])
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6, 1e7])
    ap.add_argument("--steps", type=int, default=5, help="timed steps per item (default 5)")
    ap.add_argument("--budget", type=float, default=280.0,
                    help="seconds for the whole command (default 280, under 5 min)")
    ap.add_argument("--json", type=Path, default=Path("runs/bench_gpu.json"))
    args = ap.parse_args(argv)
    if args.child:
        dim, n, device, steps = args.child
        print(json.dumps(run_item(int(dim), int(float(n)), device, int(steps))))
        return 0
    start = time.perf_counter()
    rows = []
    for device in args.devices:
        for dim in args.dims:
            last: tuple[int, float] | None = None  # (particles, seconds) of the last item
            for n in sorted(int(s) for s in args.sizes):
                left = args.budget - (time.perf_counter() - start)
                estimate = (last[1] * n / last[0]) if last else 0.0
                if left <= 0 or estimate > left:
                    rows.append({"dimension": dim, "n_target": n, "device_asked": device,
                                 "error": f"skipped: about {estimate:.0f} s, {left:.0f} s "
                                          "of the budget left"})
                    continue
                t0 = time.perf_counter()
                row = child(dim, n, device, args.steps, timeout=max(left, 30.0))
                last = (n, time.perf_counter() - t0)
                rows.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"budget_seconds": args.budget,
                                     "wall_seconds": time.perf_counter() - start,
                                     "cpu_count": os.cpu_count(), "rows": rows}, indent=2))
    print("| device | dim | particles | ms / step | pairs / s | host B / particle | "
          "GPU B / particle | note |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['device_asked']} | {r['dimension']} | {r['n_target']:.0e} | | | | | "
                  f"{r['error']} |")
            continue
        gpu = r.get("gpu_bytes_per_particle")
        ran = r["device"] + ("" if r["device"] == "cpu" else
                             " (state on the GPU)" if r.get("state_on_device") else
                             " (state on the host)")
        note = "" if r["device"] == r["device_asked"].split("-")[0] else \
            f"asked {r['device_asked']}"
        print(f"| {ran} | {r['dimension']} | {r['n_particles']:,} | "
              f"{r['ms_per_step']:.2f} | {r['pair_evaluations_per_second']:.3g} | "
              f"{r['host_bytes_per_particle']:.0f} | {'' if gpu is None else f'{gpu:.0f}'} | "
              f"{note} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
