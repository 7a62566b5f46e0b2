"""Milliseconds per step and pair evaluations per second on the GPU and on the CPU, at 1e5,
1e6 and 1e7 particles in 2D and 3D: one command for a machine with a GPU, within a time
budget (issue 16).

Each (device, dimension) runs in a fresh process that takes the sizes in turn, smallest
first, so that the CUDA kernels compile once a process (numba-cuda keeps no cache of them:
about 30 s a dimension): the lattice of ``bench_rates.make_case`` (steel-like, dx = 1 mm,
h = 1.2 dx, the paper's scheme, small random velocities so that the viscosity works) with
``compute.device`` set, one warm step (the first neighbour build, the first transfers), then
``--steps`` timed steps of the integrator (two rate evaluations each, the time integration
and the neighbour updates: what a run pays a step, outputs excepted). It prints a Markdown
table and writes ``--json``: ms per step, pair evaluations per second (those of the timed
steps over their wall time), the device the passes ran on (a run asked to use a GPU that
cannot falls back to the CPU and says so: the column shows where it ran), the seconds the
first (tiny) case took to compile, and memory per particle: the growth of the host's peak
resident set from just before the size's lattice is built (the sizes grow tenfold, so the
peak is the size's own) and, on a GPU, the growth of the device memory in use from just
before the lattice to after the timed steps (the CUDA context and the kernels excluded).

Each process gets an equal share of the budget left when it starts. A size whose estimated
time (the previous size's, scaled by the particle count) would pass the share left is
skipped and listed as such; a process that passes its share by 20 s is stopped, and the
sizes it finished are kept (the JSON is written after each process). So the command ends
within ``--budget`` seconds plus 20 s.

    python benchmarks/bench_gpu.py                        # GPU and CPU, 2D and 3D, 1e5-1e7
    python benchmarks/bench_gpu.py --devices cpu --sizes 1e4 1e5 --budget 60
    python benchmarks/bench_gpu.py --devices gpu --record-precision float32 --compare-cpu
    python benchmarks/bench_gpu.py --devices gpu cpu --dims 3 --sizes 1e5 1e6 --model quarter
    python benchmarks/bench_gpu.py --devices gpu --dims 2 --sizes 1e6 --particle-order input

``--model quarter`` (2026-12-07) times what an impact user's model adds to the lattice's
step: the block as a quarter model (in 2D a half) on a rigid wall, with the symmetry planes
through its sides (their ghosts chosen, filled and mirrored stage by stage), moving onto the
wall at 50 m/s, with an elastic case's stabilisation (the kernel gradient correction and the
hourglass control, ``"auto"``): the launches and the host's waits that those features add
to a step, which the plain lattice does not show.
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
#: the children's ``compute.record_precision`` (``--record-precision``), through the environment
PRECISION_ENV = "IMPACTSPH_BENCH_RECORD_PRECISION"
#: the children's model (``--model``: ``lattice`` or ``quarter``), through the environment
MODEL_ENV = "IMPACTSPH_BENCH_MODEL"
#: the children's ``compute.particle_order`` (``--particle-order``; bench_rates.ORDER_ENV,
#: which its lattice reads)
ORDER_ENV = "IMPACTSPH_BENCH_PARTICLE_ORDER"
#: ``--model quarter``'s speed onto its wall (m/s)
QUARTER_SPEED = 50.0


def quarter_model(data: dict, dim: int) -> dict:
    """``data`` (:func:`bench_rates.make_case`'s lattice, its origin at 0) as a quarter
    model (a half in 2D, a bar in 1D) on a rigid wall under it: a symmetry plane through
    each side at the origin but the last axis's, which the wall holds, the block moving onto
    it at :data:`QUARTER_SPEED`, with an elastic case's stabilisation (``"auto"``)."""
    unit = [[1.0 if a == b else 0.0 for a in range(dim)] for b in range(dim)]
    zero = [0.0] * dim
    body = {**data["bodies"][0], "velocity": [0.0] * (dim - 1) + [-QUARTER_SPEED]}
    return {**data, "bodies": [body],
            "boundaries": [{"type": "wall", "point": zero, "normal": unit[dim - 1]},
                           *({"type": "symmetry", "point": zero, "normal": unit[a]}
                             for a in range(dim - 1))],
            "stabilisation": {"gradient_correction": "auto", "hourglass": "auto"}}


def run_items(dim: int, sizes: list[int], device: str, steps: int, budget: float,
              compare_cpu: bool = False) -> None:
    """The items of one (device, dimension), in this process (the child): one JSON row a
    size on stdout, as each ends."""

    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_rates import current_rss_mib, make_case, peak_rss_mib

    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    started = time.perf_counter()

    def case(size: int) -> dict:
        data = make_case(size, dim)
        if os.environ.get(MODEL_ENV, "lattice") == "quarter":
            data = quarter_model(data, dim)
        data["compute"] = {**data["compute"], "device": "cpu" if device == "cpu" else "gpu",
                           "resident": device != "gpu-host",
                           "record_precision": os.environ.get(PRECISION_ENV, "float64")}
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

    t0 = time.perf_counter()
    warm = Simulation(validate_case(case(2**dim)))  # the compiled code, the CUDA context
    stepper(warm)(1e-9)
    compile_seconds = time.perf_counter() - t0
    del warm
    last: tuple[int, float] | None = None
    kept = None  # (size, dt, the GPU run's final state) for the comparison with the CPU
    for n in sorted(sizes):
        left = budget - (time.perf_counter() - started)
        estimate = last[1] * n / last[0] if last else 0.0
        if left <= 0 or estimate > left:
            print(json.dumps({"dimension": dim, "n_target": n, "device_asked": device,
                              "error": f"skipped: about {estimate:.0f} s, {left:.0f} s of "
                                       "the budget left"}), flush=True)
            continue
        item_start = time.perf_counter()
        gpu_before = gpu_used() if device != "cpu" else None
        baseline = current_rss_mib()
        data = case(n)
        t0 = time.perf_counter()
        sim = Simulation(validate_case(data))
        setup = time.perf_counter() - t0
        state = sim.state
        start_velocities(state)
        dt = stable_time_step(state, sim.problem.table, 0.3)
        resident = sim._resident is not None
        if resident:
            sim._resident.upload(state)  # the random velocities
        step = stepper(sim)
        t0 = time.perf_counter()
        step(dt)  # transfers, the first neighbour update
        warm_step = time.perf_counter() - t0
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
        row = {"dimension": dim, "n_target": n, "n_particles": state.n,
               "device_asked": device, "device": ran_on, "state_on_device": resident,
               "record_precision": data["compute"]["record_precision"],
               "particle_order": data["compute"]["particle_order"],
               "steps": steps, "compile_seconds": compile_seconds, "setup_seconds": setup,
               "warm_step_seconds": warm_step, "ms_per_step": 1e3 * wall / steps,
               "pair_evaluations_per_second": pairs / wall,
               "pairs_per_particle": pairs / (2 * steps * state.n),
               "host_bytes_per_particle": (peak_rss_mib() - baseline) * 2**20 / state.n}
        if ran_on == "gpu":
            used = gpu_used() if gpu_before is not None else None
            if used is not None:
                row["gpu_bytes_per_particle"] = (used - gpu_before) / state.n
            from numba import cuda

            row["gpu_name"] = cuda.get_current_device().name
            if isinstance(row["gpu_name"], bytes):
                row["gpu_name"] = row["gpu_name"].decode()
        if resident:  # the arrays it holds, and the preflight's estimate of its peak
            from impactsph import preflight

            held = sum(size for size, _ in sim._resident.allocated().values())
            row["gpu_held_bytes_per_particle"] = held / state.n
            checked = validate_case(data)
            estimate = preflight.estimate(checked, preflight.count_particles(checked))
            if estimate.device_memory is not None:
                row["gpu_estimate_bytes_per_particle"] = (
                    estimate.device_memory - preflight.GPU_BASE_MEMORY) / state.n
        last = (n, time.perf_counter() - item_start)
        if compare_cpu and ran_on != "cpu" and n == min(sizes):  # compared after the sizes
            kept = (n, dt, {k: np.array(a) for k, a in sim.state.arrays().items()})
        del sim, state
        print(json.dumps(row), flush=True)
    if kept is not None and time.perf_counter() - started < budget:
        n, dt, arrays = kept
        print(json.dumps({"n_target": n, "relative_difference_to_cpu":
                          difference_to_cpu(arrays, case(n), dt, steps + 1)}), flush=True)


def gpu_used() -> int | None:
    """The device's memory in use (bytes) after the pending frees, on a real GPU (None
    elsewhere; the whole device's: another process's arrays count too)."""
    import gc

    from impactsph.gpu import simulator_enabled

    gc.collect()
    if simulator_enabled():
        return None
    try:
        from numba import cuda

        if not cuda.is_available():
            return None
        context = cuda.current_context()
        context.deallocations.clear()
        free, total = context.get_memory_info()
        return total - free
    except Exception:  # noqa: BLE001 - no CUDA here: the CPU's row has no such column
        return None


def start_velocities(state) -> None:
    """The benchmark's start: random velocities of 1 m/s (so that the viscosity works), the
    same in every run and in the comparison's CPU run."""
    import numpy as np
    from bench_rates import SEED

    state.velocity[:] = np.random.default_rng(SEED).normal(0.0, 1.0, size=state.velocity.shape)


def difference_to_cpu(final: dict, data: dict, dt: float, steps: int) -> dict:
    """The same lattice, the same random velocities and ``steps`` steps of ``dt`` on the
    CPU: each field's largest difference to ``final`` (the GPU run's state arrays), over the
    field's largest size (a check at the benchmark's scale, beside ``tests/test_gpu.py``'s
    small cases). It runs after the timed sizes, so that the CPU's compilation does not eat
    their budget."""
    import numpy as np

    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    # the CPU with the GPU run's records (float32 records are compared with float32's)
    precision = data.get("compute", {}).get("record_precision", "float64")
    data = {**data, "compute": {"device": "cpu", "record_precision": precision}}
    ref = Simulation(validate_case(data))
    start_velocities(ref.state)
    for _ in range(steps):
        ref.integrator.step(ref._state, dt)
        ref._survey()
    got, want = final, ref.state.arrays()
    out = {}
    for name, b in want.items():
        a = got.get(name)
        if a is None or np.shape(a) != np.shape(b) or not np.issubdtype(np.asarray(b).dtype,
                                                                        np.floating):
            continue
        if not np.size(b):
            continue
        error = float(np.abs(np.asarray(a) - b).max())
        scale = float(np.abs(b).max())
        out[name] = error / scale if scale > 0 else error
    return out


def _text(output: bytes | str | None) -> str:
    return output.decode() if isinstance(output, bytes) else (output or "")


def child(dim: int, sizes: list[int], device: str, steps: int, timeout: float,
          compare_cpu: bool = False, launch: tuple[int, int] | None = None,
          precision: str = "float64", model: str = "lattice",
          order: str = "auto") -> list[dict]:
    """Run one (device, dimension) in a fresh process; a row a size, or the reason it has
    none. ``launch``: the GPU's ``(threads_per_block, max_registers)``
    (:func:`impactsph.gpu.launch_settings`), set in the child's environment, as are the
    records' ``precision`` (:data:`PRECISION_ENV`), the ``model`` (:data:`MODEL_ENV`) and
    the particles' ``order`` (:data:`ORDER_ENV`)."""
    from impactsph.gpu import REGISTERS_ENV, THREADS_ENV

    command = [sys.executable, __file__, "--child", str(dim), device, str(steps),
               f"{timeout:.0f}", "compare" if compare_cpu else "-", *(str(n) for n in sizes)]
    env = dict(os.environ)
    env[PRECISION_ENV] = precision
    env[MODEL_ENV] = model
    env[ORDER_ENV] = order
    if launch is not None:
        env[THREADS_ENV], env[REGISTERS_ENV] = str(launch[0]), str(launch[1])
    try:
        out = subprocess.run(command, capture_output=True, text=True, timeout=timeout + 20,
                             check=False, env=env)
        stdout, stderr, why = out.stdout, out.stderr, out.returncode
    except subprocess.TimeoutExpired as exc:
        stdout, stderr, why = _text(exc.stdout), _text(exc.stderr), None
    lines = [json.loads(line) for line in stdout.splitlines() if line.startswith("{")]
    rows = [r for r in lines if "dimension" in r]
    if launch is not None:
        for r in rows:
            r["threads_per_block"], r["max_registers"] = launch
    for extra in (r for r in lines if "dimension" not in r):  # the comparison, for its row
        for r in rows:
            if r["n_target"] == extra["n_target"]:
                r.update(extra)
    done = {r["n_target"] for r in rows}
    for n in sizes:
        if n not in done:
            tail = (stderr.strip().splitlines() or ["no message"])[-1]
            why_text = f"timed out after {timeout + 20:.0f} s" if why is None else \
                f"exit {why}: {tail}"
            rows.append({"dimension": dim, "n_target": n, "device_asked": device,
                         "error": why_text, **({"threads_per_block": launch[0],
                                                "max_registers": launch[1]} if launch else {})})
    if stderr.strip() and why:
        sys.stderr.write(stderr[-4000:])
    return sorted(rows, key=lambda r: r["n_target"])


def write_json(args: argparse.Namespace, rows: list[dict], wall: float) -> None:
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"budget_seconds": args.budget, "wall_seconds": wall,
                                     "cpu_count": os.cpu_count(), "rows": rows}, indent=2))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
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
    ap.add_argument("--threads-per-block", nargs="+", type=int, default=[128],
                    help="the GPU's threads a block, each value a process of its own "
                    "(default 128)")
    ap.add_argument("--max-registers", nargs="+", type=int, default=[0],
                    help="the pair kernel's register cap, 0 for the compiler's choice; each "
                    "value a process of its own (benchmarks/gpu_registers.py gives the "
                    "spills of each)")
    ap.add_argument("--compare-cpu", action="store_true",
                    help="at the smallest size, run the same steps on the CPU and report each "
                    "field's largest relative difference (the CPU's compilation and steps "
                    "count against the budget)")
    ap.add_argument("--record-precision", choices=("float64", "float32"), default="float64",
                    help="compute.record_precision of every run (docs/gpu.md, 'Records in "
                    "float32'); --compare-cpu then compares with the CPU's run in the same")
    ap.add_argument("--particle-order", choices=("auto", "input", "cells"), default="auto",
                    help="compute.particle_order of every run: the default's choice (auto: "
                    "the list's order for 2D lattices of 5e5 particles or more), the "
                    "lattice's own row-major numbering (input) or the neighbour list's cells' "
                    "(cells) (docs/case-files.md, 'Particle order')")
    ap.add_argument("--model", choices=("lattice", "quarter"), default="lattice",
                    help="lattice: the block at rest with random velocities (default); "
                    "quarter: the block as a quarter model on a wall, with the symmetry "
                    "planes and an elastic case's stabilisation (the module's docstring)")
    args = ap.parse_args(argv)
    if args.child:
        dim, device, steps, budget, compare, *sizes = args.child
        run_items(int(dim), [int(float(n)) for n in sizes], device, int(steps), float(budget),
                  compare == "compare")
        return 0
    start = time.perf_counter()
    rows = []
    # the GPU's launch settings, each in a process of its own (the CPU's rows take none)
    launches = [(t, r) for t in args.threads_per_block for r in args.max_registers]
    runs = [(device, dim, None if device == "cpu" else launch) for device in args.devices
            for dim in args.dims for launch in (launches if device != "cpu" else [None])]
    for k, (device, dim, launch) in enumerate(runs):
        # each process gets an equal share of what is left of the budget
        left = args.budget - (time.perf_counter() - start)
        share = left / (len(runs) - k)
        sizes = sorted(int(s) for s in args.sizes)
        if share < 10:
            rows.extend({"dimension": dim, "n_target": n, "device_asked": device,
                         "error": f"skipped: {left:.0f} s of the budget left"}
                        for n in sizes)
            continue
        for row in child(dim, sizes, device, args.steps, share, args.compare_cpu, launch,
                         args.record_precision, args.model, args.particle_order):
            row["model"] = args.model
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
        write_json(args, rows, time.perf_counter() - start)  # what has run, kept as it goes
    write_json(args, rows, time.perf_counter() - start)
    print("| device | dim | particles | ms / step | pairs / s | host B / particle | "
          "GPU B / particle (held; estimated) | compile s | to the CPU | note |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['device_asked']} | {r['dimension']} | {r['n_target']:.0e} | | | | | | | "
                  f"{r['error']} |")
            continue
        gpu = r.get("gpu_bytes_per_particle")
        gpu = "" if gpu is None else f"{gpu:.0f}"
        counted = [r.get(k) for k in ("gpu_held_bytes_per_particle",
                                      "gpu_estimate_bytes_per_particle")]
        if any(c is not None for c in counted):
            gpu += " (" + "; ".join("" if c is None else f"{c:.0f}" for c in counted) + ")"
        difference = r.get("relative_difference_to_cpu")
        to_cpu = f"{max(difference.values()):.1e}" if difference else ""
        ran = r["device"] + ("" if r["device"] == "cpu" else
                             " (state on the GPU)" if r.get("state_on_device") else
                             " (state on the host)")
        if r.get("record_precision", "float64") != "float64":
            ran += f", records in {r['record_precision']}"
        if r.get("particle_order", "auto") != "auto":
            ran += f", particle order {r['particle_order']}"
        note = "" if r["device"] == r["device_asked"].split("-")[0] else \
            f"asked {r['device_asked']}"
        if r["device"] == "gpu" and "threads_per_block" in r:
            note = (f"{r['threads_per_block']} threads a block, registers "
                    f"{r['max_registers'] or 'free'}; {note}").rstrip("; ")
        print(f"| {ran} | {r['dimension']} | {r['n_particles']:,} | "
              f"{r['ms_per_step']:.2f} | {r['pair_evaluations_per_second']:.3g} | "
              f"{r['host_bytes_per_particle']:.0f} | {gpu} | "
              f"{r['compile_seconds']:.1f} | {to_cpu} | {note} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
