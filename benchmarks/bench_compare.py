"""The rate benchmark of two source trees side by side, in one run: ``bench_rates.py`` of each
tree (its own script and its own ``src``), alternated round by round (A B A B ...) so that both
see the same machine, then the pair-evaluation rates and step times of each round, the best of
each side, and the ratio new/old.

Usage (the old tree, e.g. ``git worktree add /tmp/old 3d5868e``)::

    python benchmarks/bench_compare.py /tmp/old --sizes 1e5 1e6 --dims 2 3 --rounds 2

A ratio above 1 means the new tree (this checkout) evaluates more pairs per second.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent


def run_tree(tree: Path, sizes: list[str], dims: list[str], repeat: int) -> dict:
    """One ``bench_rates.py`` run of ``tree`` (sizes and dims only: no examples, no skins, no
    compile timing); its JSON results."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.json"
        env = dict(os.environ, PYTHONPATH=str(tree / "src"))
        cmd = [sys.executable, str(tree / "benchmarks" / "bench_rates.py"), "--sizes", *sizes,
               "--dims", *dims, "--repeat", str(repeat), "--examples", "--skins",
               "--no-compile", "--json", str(out)]
        res = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if res.returncode != 0:
            raise SystemExit(f"{tree}: bench_rates failed\n{res.stdout[-2000:]}"
                             f"\n{res.stderr[-4000:]}")
        return json.loads(out.read_text())


def sizes_of(result: dict) -> dict[tuple[int, int], dict]:
    """The per-size entries of a bench_rates JSON, by (dimension, target size)."""
    items = result.get("sizes") or result.get("results") or []
    return {(int(r["dimension"]), int(r["n_target"])): r for r in items}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", type=Path, help="the other source tree (a checkout or worktree)")
    ap.add_argument("--sizes", nargs="+", default=["1e5", "1e6"])
    ap.add_argument("--dims", nargs="+", default=["2", "3"])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", metavar="PATH", help="also write every round as JSON")
    args = ap.parse_args(argv)
    rounds = []
    for k in range(args.rounds):
        for label, tree in (("old", args.old.resolve()), ("new", HERE)):
            print(f"round {k + 1}: {label} ({tree})", flush=True)
            rounds.append((label, sizes_of(run_tree(tree, args.sizes, args.dims,
                                                    args.repeat))))
    keys = sorted({key for _, r in rounds for key in r})
    print(f"\n{'dim':>3} {'N':>9} | {'old pairs/s (rounds)':>28} | {'new pairs/s (rounds)':>28} "
          f"| best new/old | step new/old")
    table = []
    for key in keys:
        old = [r[key] for lab, r in rounds if lab == "old" and key in r]
        new = [r[key] for lab, r in rounds if lab == "new" and key in r]
        po = [e["pair_evaluations_per_second"] for e in old]
        pn = [e["pair_evaluations_per_second"] for e in new]
        so = min(e["step_seconds"] for e in old)
        sn = min(e["step_seconds"] for e in new)
        row = {"dimension": key[0], "n_target": key[1], "old": po, "new": pn,
               "best_ratio": max(pn) / max(po), "step_ratio": sn / so}
        table.append(row)
        print(f"{key[0]:>3} {key[1]:>9} | {' '.join(f'{p:.3e}' for p in po):>28} | "
              f"{' '.join(f'{p:.3e}' for p in pn):>28} | {row['best_ratio']:>12.3f} | "
              f"{row['step_ratio']:.3f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"rounds": [
            {"label": lab, "results": [{"key": list(k), **v} for k, v in r.items()]}
            for lab, r in rounds], "table": table}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
