"""Where a step on the GPU goes: each kernel's device time (CUDA events around each launch and
each copy), the host's time to issue it, and the step's wall time with and without the events
(issue 16).  No profiler needed: numba-cuda's launches and copies are wrapped in this process.

The case is ``bench_gpu``'s (``bench_rates.make_case``: a steel lattice, random velocities of
1 m/s), the state on the device, one warm step, ``--steps`` steps timed as a run takes them
(the step and its survey), then ``--steps`` more with each operation between two events.  It
prints one table a run (operations by their device time a step) and writes ``--json``.

    python benchmarks/gpu_profile.py --dim 3 --size 1e6 --steps 10
    IMPACTSPH_CUDA_MAX_REGISTERS=128 python benchmarks/gpu_profile.py --dim 3 --size 1e6

What the columns mean: ``device ms/step``: the sum over a step of the time between the events
either side of an operation (the operation's time on the device, when the stream has no other
work queued, which holds here: one stream); ``host us/call``: the Python time to issue it (the
launch's argument checks and packing); ``calls/step``.  The events' own cost shows as the
difference between the two wall times.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dim", type=int, default=3, choices=(2, 3))
    parser.add_argument("--size", type=float, default=1e6)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--record-precision", choices=("float64", "float32"),
                        default="float64", help="compute.record_precision (docs/gpu.md)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)

    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_gpu import gpu_used, start_velocities
    from bench_rates import make_case
    from numba import cuda

    from impactsph.gpu import launch_settings, simulator_enabled
    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    data = make_case(int(args.size), args.dim)
    data["compute"] = {"device": "gpu", "resident": True,
                       "record_precision": args.record_precision}

    if simulator_enabled():  # the GPU backend in numba's CUDA simulator (a check of this script)
        from impactsph import simulation
        from impactsph.gpu import GpuRates

        simulation.select_backend = (lambda device, dim, *options, cpu_only=None:
                                     GpuRates(dim, *options))
    used0 = gpu_used() or 0
    t0 = time.perf_counter()
    sim = Simulation(validate_case(data))
    setup = time.perf_counter() - t0
    r = sim._resident
    if r is None:
        print("the state is not on the device:", getattr(sim.solver.backend, "device", "cpu"))
        return 1
    state = sim._state
    start_velocities(state)
    dt = stable_time_step(state, sim.problem.table, 0.3)
    r.upload(state)

    def step() -> None:
        r.step(state, dt)
        sim._survey()

    t0 = time.perf_counter()
    step()  # the first build, the first launches of each kernel
    warm = time.perf_counter() - t0
    sim._fold()
    pairs0 = sim.solver.pair_evaluations
    t0 = time.perf_counter()
    for _ in range(args.steps):
        step()
    wall = (time.perf_counter() - t0) / args.steps
    sim._fold()
    pairs = (sim.solver.pair_evaluations - pairs0) / args.steps

    used = gpu_used() or 0

    # each operation between two events on the run's stream (in numba's CUDA simulator, which
    # has no timed events and runs each operation as it is issued: the host's time alone)
    stream = r.stream
    simulated = simulator_enabled()
    records: list[tuple] = []  # (operation, event before, event after, host seconds)

    depth = [0]  # the simulator runs device functions as kernels too: the outermost counts

    def timed(name: str, call):
        if depth[0]:
            return call()
        depth[0] += 1
        try:
            return _timed(name, call)
        finally:
            depth[0] -= 1

    def _timed(name: str, call):
        if simulated:
            h0 = time.perf_counter()
            result = call()
            records.append((name, None, time.perf_counter() - h0, time.perf_counter() - h0))
            return result
        e0, e1 = cuda.event(timing=True), cuda.event(timing=True)
        e0.record(stream)
        h0 = time.perf_counter()
        result = call()
        h1 = time.perf_counter()
        e1.record(stream)
        records.append((name, e0, e1, h1 - h0))
        return result

    if simulated:
        from numba.cuda.simulator import kernel as launches
        from numba.cuda.simulator.cudadrv import devicearray as arrays

        launch_class, array_class = launches.FakeCUDAKernel, arrays.FakeCUDAArray

        def kernel_name(configured) -> str:
            return configured.fn.__name__
    else:
        from numba.cuda import dispatcher
        from numba.cuda.cudadrv import devicearray as arrays

        launch_class, array_class = dispatcher._LaunchConfiguration, arrays.DeviceNDArrayBase

        def kernel_name(configured) -> str:
            return configured.dispatcher.py_func.__name__

    launch = launch_class.__call__
    to_device = array_class.copy_to_device
    to_host = array_class.copy_to_host

    def launch_timed(self, *a):
        return timed(kernel_name(self), lambda: launch(self, *a))

    def to_device_timed(self, ary, stream=0):
        kind = "copy D2D" if hasattr(ary, "copy_to_host") else "copy H2D"
        return timed(kind, lambda: to_device(self, ary, stream=stream))

    def to_host_timed(self, ary=None, stream=0):
        return timed("copy D2H", lambda: to_host(self, ary, stream=stream))

    launch_class.__call__ = launch_timed
    array_class.copy_to_device = to_device_timed
    array_class.copy_to_host = to_host_timed
    try:
        t0 = time.perf_counter()
        for _ in range(args.steps):
            step()
        wall_events = (time.perf_counter() - t0) / args.steps
        stream.synchronize()
    finally:
        launch_class.__call__ = launch
        array_class.copy_to_device = to_device
        array_class.copy_to_host = to_host

    device_ms: dict[str, float] = defaultdict(float)
    host_s: dict[str, float] = defaultdict(float)
    calls: dict[str, int] = defaultdict(int)
    for name, e0, e1, host in records:
        device_ms[name] += 1e3 * e1 if e0 is None else cuda.event_elapsed_time(e0, e1)
        host_s[name] += host
        calls[name] += 1
    steps = args.steps
    tpb, regs = launch_settings()
    print(f"\n{args.dim}D, {state.n:,} particles, records in {args.record_precision}, threads "
          f"a block {tpb}, register cap {regs or 'none'}: {1e3 * wall:.2f} ms a step "
          f"({pairs / wall:.3g} pair evaluations/s, {pairs / (2 * state.n):.1f} a particle an "
          f"evaluation); with the events "
          f"{1e3 * wall_events:.2f} ms; GPU memory {(used - used0) / state.n:.0f} B a particle "
          f"(the kernels' code included); setup {setup:.1f} s, warm step {warm:.2f} s")
    print("| operation | calls/step | device ms/step | host us/call |")
    print("| --- | --- | --- | --- |")
    rows = []
    for name in sorted(device_ms, key=device_ms.get, reverse=True):
        row = {"operation": name, "calls_per_step": calls[name] / steps,
               "device_ms_per_step": device_ms[name] / steps,
               "host_us_per_call": 1e6 * host_s[name] / calls[name]}
        rows.append(row)
        print(f"| {name} | {row['calls_per_step']:.1f} | {row['device_ms_per_step']:.3f} | "
              f"{row['host_us_per_call']:.0f} |")
    device_total = sum(device_ms.values()) / steps
    host_total = sum(host_s.values()) / steps
    print(f"| all | {len(records) / steps:.1f} | {device_total:.3f} | "
          f"{1e6 * host_total / max(len(records) / steps, 1):.0f} |")
    print(f"device busy {device_total:.2f} ms of {1e3 * wall:.2f} ms a step; issuing the "
          f"operations took the host {1e3 * host_total:.2f} ms a step")
    if args.json:
        out = {"dimension": args.dim, "n_particles": state.n, "threads_per_block": tpb,
               "max_registers": regs, "record_precision": args.record_precision,
               "ms_per_step": 1e3 * wall,
               "ms_per_step_with_events": 1e3 * wall_events,
               "pair_evaluations_per_second": pairs / wall,
               "gpu_bytes_per_particle": (used - used0) / state.n,
               "device_ms_per_step": device_total, "host_ms_per_step": 1e3 * host_total,
               "operations": rows, "numpy": np.__version__}
        existing = json.loads(args.json.read_text()) if args.json.exists() else []
        args.json.write_text(json.dumps(existing + [out], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
