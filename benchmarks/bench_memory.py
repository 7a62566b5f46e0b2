"""Memory per particle, array by array: every numpy array reachable from a ``Simulation``
after a few steps, each array's memory counted once (views are counted with their base),
in bytes per particle, largest first (issue 16's target: 1 kB per particle in 3D).

    .venv/bin/python benchmarks/bench_memory.py [--dim 3] [--n 1e5] [--scheme av]
        [--steps 2] [--wall] [--h-over-dx 1.3] [--skin 0.05] [--json PATH]
        [--device gpu [--simulator]] [--record-precision float32] [--yield-stress 5e8]

The case is ``bench_ac_cost.py``'s lattice (dx = 1 mm, h = 1.2 dx, elastic steel, random
velocities of about 1 m/s, the paper's scheme: no stabilisation), ``--scheme`` its viscosity;
``--yield-stress`` makes the steel elastic-perfectly plastic (von Mises), whose return map
changes the material state (the step's start copy then keeps its first three columns).
Unlike ``bench_rates.py``'s peak-RSS growth this counts only the run's own arrays (not numba's
or numpy's workspace, nor memory the allocator keeps), and says which object holds each.
With ``--device gpu`` the run's state lives on the GPU (``compute.resident``) and the device's
arrays are counted instead (each allocation once; not the kernels' code, nor the memory
numba-cuda keeps for deferred frees); ``--simulator`` runs it in numba's CUDA simulator, where
a small lattice is all that fits in a minute: its list has fewer neighbours a particle than a
large one's (the list's neighbours a particle are printed).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def arrays_of(root: object, name: str = "sim", depth: int = 14,
              device: bool = False) -> dict[int, tuple[int, str]]:
    """:func:`impactsph.gpu_memory.arrays_of` (imported at the call: ``--simulator`` sets
    numba's environment before impactsph imports numba)."""
    from impactsph.gpu_memory import arrays_of as walk

    return walk(root, name, depth, device)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dim", type=int, default=3, choices=(1, 2, 3))
    parser.add_argument("--n", type=float, default=1e5, help="target particle count")
    parser.add_argument("--scheme", default="av", help="viscosity scheme (default av)")
    parser.add_argument("--steps", type=int, default=2)
    parser.add_argument("--wall", action="store_true",
                        help="a free-slip wall under the lattice (its ghosts: the extended "
                        "arrays, whose first rows the state's fields then are)")
    parser.add_argument("--h-over-dx", type=float, default=None,
                        help="the kernel's width in spacings (default: the lattice's 1.2, the "
                        "width the recorded numbers were taken at; the cases' default is 1.3)")
    parser.add_argument("--skin", type=float, default=None,
                        help="the neighbour list's skin, time.neighbour_skin (default: the "
                        "case's 0.1 of the support); a thinner skin stores fewer pairs and "
                        "rebuilds the list more often")
    parser.add_argument("--device", choices=("cpu", "gpu"), default="cpu",
                        help="gpu: the run's state on the GPU (compute.resident), and the "
                        "device's arrays counted, not the host's (on a GPU, or in numba's CUDA "
                        "simulator with --simulator)")
    parser.add_argument("--simulator", action="store_true",
                        help="with --device gpu: numba's CUDA simulator instead of a GPU (slow: "
                        "a few thousand particles)")
    parser.add_argument("--record-precision", choices=("float64", "float32"), default=None,
                        help="compute.record_precision (default: the case's float64)")
    parser.add_argument("--yield-stress", type=float, default=None,
                        help="Pa: an elastic-perfectly plastic steel (default: elastic)")
    parser.add_argument("--json", type=Path, default=None, help="also write the table here")
    args = parser.parse_args(argv)
    if args.simulator:
        if "numba" in sys.modules:
            parser.error("--simulator: numba was imported before the simulator could be set")
        os.environ["NUMBA_ENABLE_CUDASIM"] = "1"

    sys.path.insert(0, str(HERE))
    from bench_ac_cost import lattice_case
    from llvmlite.binding import get_host_cpu_name as host_cpu_name

    from impactsph import __version__
    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    case = lattice_case(args.dim, int(args.n), args.scheme)
    if args.h_over_dx is not None:
        case["kernel"]["h_over_dx"] = args.h_over_dx
    if args.yield_stress is not None:
        case["materials"]["m"].update(model="elastic_plastic", yield_stress=args.yield_stress)
    if args.skin is not None:
        case["time"]["neighbour_skin"] = args.skin
    if args.wall:
        normal = [0.0] * args.dim
        normal[-1] = 1.0
        case["boundaries"] = [{"type": "wall", "point": [0.0] * args.dim, "normal": normal,
                               "slip": "free"}]
    case["compute"] = {}
    if args.device == "gpu":
        case["compute"] = {"device": "gpu", "resident": True}
    if args.record_precision is not None:
        case["compute"]["record_precision"] = args.record_precision
    if args.simulator:  # the simulator in place of the GPU (the backend refuses it otherwise)
        from impactsph import simulation
        from impactsph.gpu import GpuRates

        simulation.select_backend = (lambda device, dim, *options, cpu_only=None:
                                     GpuRates(dim, *options))
    sim = Simulation(validate_case(case))
    sim.state.velocity[:] = np.random.default_rng(1).normal(size=sim.state.velocity.shape)
    dt = 0.1 * stable_time_step(sim.state, sim.problem.table, 0.3)
    resident = sim._resident
    if args.device == "gpu":
        if resident is None:
            sys.exit(f"--device gpu: the run's state is not on a GPU "
                     f"({sim.solver.backend.__class__.__name__}); is one there, or "
                     f"--simulator given?")
        resident.upload(sim.state)
    for _ in range(args.steps):
        if resident is not None:
            resident.step(sim.state, dt)
        else:
            sim.integrator.step(sim.state, dt)
    n = sim.state.n
    rows = sorted(arrays_of(sim, device=args.device == "gpu").values(), reverse=True)
    total = sum(size for size, _ in rows)
    h_over_dx = case["kernel"]["h_over_dx"]
    skin = sim.solver.skin_fraction
    lists = resident if resident is not None else sim.solver.neighbours
    pairs = lists.indices.shape[0]
    print(f"impactsph {__version__}: {args.dim}D lattice, {n} particles, h = {h_over_dx} dx, "
          f"skin {skin} of the support, {args.scheme}, "
          f"{'elastic' if args.yield_stress is None else 'plastic'} steel, "
          f"{'a wall under it, ' if args.wall else ''}"
          f"records in {case['compute'].get('record_precision', 'float64')}, "
          f"after {args.steps} steps: {total / n:.0f} B per particle in "
          f"{len(rows)} {'device' if args.device == 'gpu' else 'host'} arrays; the "
          f"list's {pairs / n:.1f} neighbours a particle")
    print(f"{'B/particle':>10}  array")
    for size, path in rows:
        if size >= 2 * n:  # the per-particle arrays (the rest: tables, small buffers)
            print(f"{size / n:10.1f}  {path}")
    small = [size for size, _ in rows if size < 2 * n]
    print(f"{sum(small) / n:10.1f}  (the rest: {len(small)} small arrays)")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "version": __version__, "machine": platform.machine(), "cpu": host_cpu_name(),
            "dim": args.dim, "particles": n, "h_over_dx": h_over_dx, "skin": skin,
            "scheme": args.scheme, "yield_stress": args.yield_stress,
            "wall": args.wall, "device": args.device, "simulator": args.simulator,
            "record_precision": case["compute"].get("record_precision", "float64"),
            "neighbours_per_particle": pairs / n,
            "bytes_per_particle": total / n,
            "arrays": [{"path": p, "bytes_per_particle": s / n} for s, p in rows]}, indent=1))


if __name__ == "__main__":
    main()
