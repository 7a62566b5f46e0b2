"""Time the neighbour-list build (``NeighbourList.build``, ms, best of ``--repeat``) here and,
side by side in the same run, in other source trees.

    .venv/bin/python benchmarks/bench_neighbours.py [--trees /tmp/head] [--inputs ...]
        [--threads 2] [--rounds 2] [--repeat 7]

The inputs, each built as the solver builds it (``support = 2 h_max``, a skin of 0.1 of the
support, the inner list of AC's correction at half the support):

- ``2d-lattice``, ``3d-lattice``: square and cubic lattices of about 1e5 particles (spacing 1,
  each particle moved by a normal deviate of 0.1), ``h = 1.3``;
- ``2d-stretched``, ``3d-stretched``: the same with 5% of the particles at ``h = 1.6`` (a
  smoothing length per particle, as ``kernel.max_stretch`` gives: a radius per pair);
- ``taylor``: the paper's Taylor bar after 5 us, its particles and the anvil's ghosts (1,482
  rows);
- ``taylor3d``: the 3D Taylor cylinder after 1 us (its stretched smoothing lengths, the
  ghosts of its wall and symmetry planes: about 24,000 rows).

Each tree runs in a new process per round (``PYTHONPATH=TREE/src``), the trees alternating,
so that a busy spell of a shared machine falls on both.  Before timing, each process checks
that its list is the first tree's to the bit (the lists' order, offsets, entries, splits and
inner lists are hashed), so a faster build that changed the list would be reported, not
hidden.  (A tree from before 2026-12-07 holds the inner list as a list of its own, and its
rows without the inner entries first: its hash differs wherever a list has an inner list.)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
INPUTS = ("2d-lattice", "3d-lattice", "2d-stretched", "3d-stretched", "taylor", "taylor3d")


def _lattice(dim: int, stretched: bool):
    import numpy as np

    m = round(1e5 ** (1.0 / dim))
    axes = np.meshgrid(*[np.arange(m, dtype=float)] * dim, indexing="ij")
    rng = np.random.default_rng(1)
    x = np.stack(axes, -1).reshape(-1, dim) + 0.1 * rng.standard_normal((m**dim, dim))
    h = np.full(x.shape[0], 1.3)
    if stretched:
        h[rng.random(x.shape[0]) < 0.05] = 1.6
        return x, 2.0 * h.max(), 0.1 * 2.0 * h.max(), 0.5, h
    return x, 2.6, 0.26, 0.5, None


def _from_case(name: str, end: str):
    """The arguments of the solver's last build of a case run to ``end``."""
    import numpy as np

    from impactsph import Simulation, load_case
    from impactsph.kernels import SUPPORT_RADIUS

    sim = Simulation(load_case(name, ["output.figures=false", f"time.end={end}"]))
    sim.run()
    solver, state = sim.solver, sim.state
    x = solver._ext["x"] if solver._ext is not None else state.position
    h = solver._ext["h"] if solver._ext is not None else state.smoothing_length
    support = SUPPORT_RADIUS * float(state.smoothing_length.max())
    varied = solver.max_stretch > 1.0 or float(h.max()) > float(h.min())
    return (np.ascontiguousarray(x), support, solver.skin_fraction * support,
            solver.viscosity.inner_reach, np.ascontiguousarray(h) if varied else None)


def arguments(name: str):
    """``(x, support, skin, inner_reach, h)`` of input ``name``."""
    if name.endswith("lattice") or name.endswith("stretched"):
        return _lattice(int(name[0]), name.endswith("stretched"))
    return _from_case(name, "5e-6" if name == "taylor" else "1e-6")


def measure(names: list[str], repeat: int) -> dict[str, list]:
    """Per input: the best build time (s), the rows, the entries and the list's hash."""
    from impactsph.neighbours import NeighbourList

    out = {}
    for name in names:
        x, support, skin, reach, h = arguments(name)
        nl = NeighbourList.build(x, support, skin, reach, h)  # compiles
        digest = hashlib.sha256()
        # (the inner list as held since 2026-12-07, and as a tree before then held it)
        inner = [getattr(nl, name, None) for name in ("inner_ends", "inner_offsets",
                                                      "inner_indices")]
        for part in (nl.order, nl.offsets, nl.indices, nl.splits, *inner):
            if part is not None:
                digest.update(part.tobytes())
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            NeighbourList.build(x, support, skin, reach, h)
            best = min(best, time.perf_counter() - t0)
        out[name] = [best, int(x.shape[0]), int(nl.n_pairs), digest.hexdigest()[:16]]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trees", nargs="*", default=[], help="other source trees to compare")
    ap.add_argument("--inputs", nargs="+", default=list(INPUTS), choices=INPUTS)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--json", type=Path, help="write every number here")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.inputs, args.repeat)))
        return 0
    trees = [HERE.parent] + [Path(t).resolve() for t in args.trees]
    results: dict[str, list[dict[str, list]]] = {str(t): [] for t in trees}
    for _ in range(args.rounds):
        for tree in trees:
            env = dict(os.environ, PYTHONPATH=str(tree / "src"),
                       NUMBA_NUM_THREADS=str(args.threads))
            out = subprocess.run([sys.executable, __file__, "--worker", "--inputs",
                                  *args.inputs, "--repeat", str(args.repeat)],
                                 env=env, capture_output=True, text=True, check=True)
            results[str(tree)].append(json.loads(out.stdout.strip().splitlines()[-1]))
    here = results[str(trees[0])]
    print(f"{args.threads} thread(s), best of {args.repeat} builds per process, ms (a column "
          f"per round; trees separated by |)")
    for name in args.inputs:
        rows, entries, digest = here[0][name][1:]
        line = [f"{name:<13} {rows:>7} rows {entries:>9} entries"]
        for tree in trees:
            line.append(" ".join(f"{r[name][0] * 1e3:7.2f}" for r in results[str(tree)]))
        if len(trees) > 1:
            other = results[str(trees[1])]
            ratio = min(r[name][0] for r in here) / min(r[name][0] for r in other)
            same = all(r[name][3] == digest for t in trees for r in results[str(t)])
            line.append(f"best here / best {trees[1].name}: {ratio:.2f}, "
                        f"{'same lists' if same else 'LISTS DIFFER'}")
        print(" | ".join(line))
    print("columns: " + " | ".join(str(t) for t in trees))
    if args.json:
        args.json.write_text(json.dumps({"threads": args.threads, "results": results},
                                        indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
