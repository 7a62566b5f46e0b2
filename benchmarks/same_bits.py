"""Whether source trees give the same bits: the SHA-256 of every state array after a fixed
number of steps of each case, each tree in a process of its own (``TREE/src`` as its
impactsph), side by side with this tree's.

    .venv/bin/python benchmarks/same_bits.py                    # this tree's hashes
    .venv/bin/python benchmarks/same_bits.py --trees /tmp/before [--cases taylor bars]

A change meant to leave every result alone (a faster loop, a pass compiled otherwise, a
copy skipped) should print "same" on every row against the tree before it; the exit status
is 1 where a row differs.  The cases cover the built-in problems, both integrators, plane
stress, axisymmetry, 3D and the smoothing length that follows the stretch (2D and 3D), in 20
to 300 steps (about 30 s for all on two cores, compiled).
Results do not depend on numba's thread count (``tests/test_threads.py``), so the workers
run with this process's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _trees import worker_result  # noqa: E402

#: name: (built-in case, overrides)
CASES: dict[str, tuple[str, list[str]]] = {
    "taylor": ("taylor", ["time.max_steps=150"]),
    "taylor-ssp_rk3": ("taylor", ["time.max_steps=120", "time.integrator=ssp_rk3"]),
    "taylor-plane_stress": ("taylor", ['two_dimensional="plane_stress"',
                                       "time.max_steps=100"]),
    "cantilever": ("cantilever", ["time.max_steps=300"]),
    "cantilever-ssp_rk3": ("cantilever", ["time.max_steps=100", "time.integrator=ssp_rk3"]),
    "rings": ("rings", ["time.max_steps=150"]),
    "bars": ("bars", ["time.max_steps=300"]),
    "taylor_axisymmetric": ("taylor_axisymmetric", ["time.max_steps=150"]),
    "taylor3d": ("taylor3d", ["time.max_steps=20"]),
    "plates": ("plates", ["time.max_steps=200"]),
    # the smoothing length that follows the stretch (set at each list build; the 1.23 of
    # "auto" reached in 2D, 1.20 in 3D)
    "taylor-stretch": ("taylor", ["kernel.max_stretch=1.23", "time.max_steps=300"]),
    "taylor3d-stretch": ("taylor3d", ["kernel.max_stretch=1.23", "time.max_steps=40",
                                      "bodies.0.geometry.spacing=8e-4"]),
}


def state_hash(case: str, overrides: list[str]) -> dict[str, Any]:
    """The steps run and the SHA-256 of every state array (in name order) after running
    the built-in ``case`` with ``overrides`` (figures off)."""
    import numpy as np

    from impactsph import Simulation, load_case

    sim = Simulation(load_case(case, ["output.figures=false", *overrides]))
    sim.run()
    digest = hashlib.sha256()
    for name, values in sorted(sim.state.arrays().items()):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(values).tobytes())
    return {"steps": int(sim.state.step), "sha256": digest.hexdigest()}


def worker(names: list[str]) -> dict[str, Any]:
    """Each named case's :func:`state_hash`, in this process's impactsph."""
    import impactsph

    return {"impactsph": str(Path(impactsph.__file__).parent),
            "cases": {name: state_hash(*CASES[name]) for name in names}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trees", nargs="*", type=Path, default=[],
                    help="other source trees to compare with this one")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--json", type=Path, help="write every hash here")
    ap.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker)))
        return 0
    import numba

    trees = [HERE.parent, *args.trees]
    results = [worker_result(__file__, tree, args.cases, numba.get_num_threads())
               for tree in trees]
    for tree, result in zip(trees, results, strict=True):
        print(f"{tree}: impactsph from {result['impactsph']}")
    differs = False
    for name in args.cases:
        rows = [r["cases"][name] for r in results]
        same = all(r == rows[0] for r in rows[1:])
        differs |= not same
        hashes = "  ".join(f"{r['sha256'][:16]} ({r['steps']} steps)" for r in rows)
        verdict = "" if len(rows) == 1 else ("  same" if same else "  DIFFERS")
        print(f"{name:22s} {hashes}{verdict}")
    if args.json:
        args.json.write_text(json.dumps({str(t): r for t, r in zip(trees, results,
                                                                    strict=True)}, indent=1))
    return 1 if differs else 0


if __name__ == "__main__":
    sys.exit(main())
