"""What a staggered (one-evaluation) step's two neighbour loops would cost, measured on the pair
pass: the pass with its first loop cut down to the kinematic sums alone (the velocity
gradient, as a staggered step's strain-rate loop would make them) and to the force sums alone
(the stress and viscous accelerations and the viscous heating), each timed against the whole
pass on the same captured inputs (``bench_pass_ab.py``).

    .venv/bin/python benchmarks/bench_split_loops.py [--cases 2d 3d taylor] [--rounds 4]

The midpoint step evaluates the rates twice a step (docs/modelling.md); a staggered step
(stress from the half-step velocity, forces from the new stress) would run the two loops once
each.  So ``kinematic + forces`` against 2 is what such a step would save on the pair pass
(benchmarks/README.md, "Why not one rate evaluation a step").  Each variant is made in a
temporary ``git worktree`` of HEAD whose ``physics/passes.py`` is this tree's (uncommitted
changes included) with the other sums' lines deleted from ``particle_rates``' first loop
(LLVM drops what then feeds nothing), and timed against this tree's whole pass; both keep
the per-particle part after the loop, which a real split would share out, so their sum
overstates the split a little.  Timing only: the variants' outputs are not rates.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PASSES = Path("src/impactsph/physics/passes.py")
LOOP_START = "    for k in range(first, last):\n        j = listed[k]"
LOOP_END = "    cont = -(L00 + L11 + L22)"
#: the accumulations each variant deletes from the first loop
DELETED = {
    "kinematic": r"G[012] \+= ws[012]|T[0-2][0-2] \+= .*|a[012] \+= sa[012]"
                 r"|w[012] \+= visc \* d[012]|de_v \+= .*",
    "forces": r"L[0-2][0-2] \+= velocity_gradient_pair.*|T[0-2][0-2] \+= .*",
}


def variant_source(source: str, variant: str) -> str:
    """``passes.py`` with the first loop of ``particle_rates`` cut down to ``variant``."""
    start, end = source.index(LOOP_START), source.index(LOOP_END)
    loop = re.sub(rf"(?m)^\s+({DELETED[variant]})\n", "", source[start:end])
    # an ``if DIM > 1:`` left with nothing in it (the sums a1, a2)
    loop = re.sub(r"(?m)^(\s+)if DIM > 1:\n\1if DIM > 2:\n", "", loop)
    return source[:start] + loop + source[end:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", nargs="+", default=["2d", "3d", "taylor"])
    parser.add_argument("--rounds", type=int, default=4)
    args = parser.parse_args()
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"),
               IMPACTSPH_PARALLEL=os.environ.get("IMPACTSPH_PARALLEL", "1"))
    source = (REPO / PASSES).read_text()
    with tempfile.TemporaryDirectory(prefix="split-loops-") as scratch:
        for variant in DELETED:
            tree = Path(scratch) / variant
            subprocess.run(["git", "-C", str(REPO), "worktree", "add", "-q", "--detach",
                            str(tree), "HEAD"], check=True)
            try:
                (tree / PASSES).write_text(variant_source(source, variant))
                print(f"--- {variant} loop alone ('here') against the whole pair pass "
                      f"('other'):", flush=True)
                subprocess.run([sys.executable, str(tree / "benchmarks" / "bench_pass_ab.py"),
                                str(REPO), "--cases", *args.cases, "--passes", "pair_pass",
                                "--rounds", str(args.rounds)],
                               env=dict(env, PYTHONPATH=str(tree / "src")), check=True)
            finally:
                subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force",
                                str(tree)], check=False)


if __name__ == "__main__":
    main()
