"""Calibration of the preflight estimates (:mod:`impactsph.preflight`): the peak memory of real
runs against :func:`~impactsph.preflight.memory_estimate`, and the pair rate of real runs.

    .venv/bin/python benchmarks/calibrate_preflight.py [--quick] [--json PATH]

Each item runs in a fresh process: ``run_case`` (the path ``impactsph run`` takes: snapshots,
history, summary, and figures where the item says so) on a case of a given size, after a tiny
warm-up run that loads the compiled kernels.  The peak resident set (``ru_maxrss``) of the
process is compared with the preflight estimate; ``base`` is the resident set after the
warm-up (the process's own part, :data:`~impactsph.preflight.BASE_MEMORY`) and ``growth`` the
rise of the peak above it, against the estimate less the base.  ``steps s`` is the wall time
of the run's steps (``wall_seconds``) and ``est s`` the preflight's estimate of it, with the
pair rate it assumes (stored by earlier runs, or the default).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def block_case(dim: int, side: int, *, wall: bool, scheme: str, snapshots: int,
               steps: int, figures: bool = False) -> dict:
    dx = 1e-3
    case = {
        "name": f"cal_{dim}d_{side}", "dimension": dim,
        "materials": {"m": {"model": "bar" if dim == 1 else "elastic", "density": 7850.0,
                            "youngs_modulus": 2e11}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0] * (dim - 1) + [-10.0],
                    "geometry": {"origin": [0.0] * dim, "size": [side * dx] * dim,
                                 "spacing": dx}}],
        "kernel": {"h_over_dx": 1.3},
        "viscosity": {"scheme": scheme},
        "time": {"end": 1.0, "max_steps": steps},
        "output": {"figures": figures,
                   "snapshot_times": [k * 1e-10 for k in range(snapshots)]},
    }
    if wall:
        case["boundaries"] = [{"point": [0.0] * dim, "normal": [0.0] * (dim - 1) + [1.0]}]
    return case


def current_rss() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def child(spec: dict) -> dict:
    from impactsph.loading import validate_case
    from impactsph.preflight import preflight
    from impactsph.runner import run_case

    case = validate_case(spec["case"])
    warm = validate_case(block_case(case.dimension, 4, wall=bool(case.boundaries),
                                    scheme=case.viscosity.scheme, snapshots=1, steps=2,
                                    figures=case.output.figures))
    with tempfile.TemporaryDirectory() as tmp:
        run_case(warm, Path(tmp) / "warm")
        gc.collect()
        base = current_rss()
        peak_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        report = preflight(case)
        t0 = time.perf_counter()
        summary = run_case(case, Path(tmp) / "run")
        wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    est = report.estimate
    return {"label": spec["label"], "n": est.total, "steps": summary["n_steps"],
            "base": base, "peak_before": peak_before, "peak": peak,
            "growth": peak - base, "estimate": est.memory,
            "estimate_growth": est.memory - _base(), "wall_seconds": wall,
            "pair_rate": summary["pair_evaluations_per_second"],
            "run_seconds": summary["wall_seconds"], "estimate_seconds": est.seconds,
            "assumed_pair_rate": est.pair_rate,
            "pairs_per_particle": est.pairs_per_particle}


def _base() -> float:
    from impactsph.preflight import BASE_MEMORY

    return BASE_MEMORY


def items(quick: bool) -> list[dict]:
    out = []
    sides2 = (100, 300) if quick else (100, 300, 600)
    for side in sides2:
        out.append({"label": f"2D AV block {side}^2",
                    "case": block_case(2, side, wall=False, scheme="av", snapshots=0,
                                       steps=3)})
        out.append({"label": f"2D AC wall 5 snapshots {side}^2",
                    "case": block_case(2, side, wall=True, scheme="ac", snapshots=5,
                                       steps=8)})
    for side in ((30,) if quick else (30, 50)):
        out.append({"label": f"3D AC wall {side}^3",
                    "case": block_case(3, side, wall=True, scheme="ac", snapshots=0,
                                       steps=3)})
    for steps in ((20_000,) if quick else (20_000, 100_000)):
        out.append({"label": f"1D 50 particles {steps} steps, figures",
                    "case": block_case(1, 50, wall=False, scheme="av", snapshots=0,
                                       steps=steps, figures=True)})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--quick", action="store_true", help="fewer and smaller items")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(json.loads(args.child))))
        return 0
    results = []
    print(f"{'item':<36} {'N':>9} {'steps':>7} {'base MB':>8} {'peak MB':>8} "
          f"{'est MB':>8} {'growth':>8} {'est gr.':>8} {'est/peak':>8} {'pairs/s':>9} "
          f"{'steps s':>8} {'est s':>8}")
    for spec in items(args.quick):
        proc = subprocess.run([sys.executable, __file__, "--child", json.dumps(spec)],
                              capture_output=True, text=True, check=False)
        if proc.returncode:
            print(f"{spec['label']}: failed\n{proc.stderr[-2000:]}")
            continue
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        results.append(r)
        print(f"{r['label']:<36} {r['n']:>9} {r['steps']:>7} {r['base'] / 1e6:>8.0f} "
              f"{r['peak'] / 1e6:>8.0f} {r['estimate'] / 1e6:>8.0f} "
              f"{r['growth'] / 1e6:>8.0f} {r['estimate_growth'] / 1e6:>8.0f} "
              f"{r['estimate'] / r['peak']:>8.2f} {r['pair_rate']:>9.3g} "
              f"{r['run_seconds']:>8.3g} {r['estimate_seconds']:>8.3g}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
