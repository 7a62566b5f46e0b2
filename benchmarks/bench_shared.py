"""Steady on a shared machine (issue 16): a case run alone, then two copies of it started side
by side, then one copy beside a busy loop that holds one core (another job), each with
``compute.threads = "auto"`` (the default: the thread governor, :mod:`impactsph.threads`) and
with the threads fixed at numba's count (what every run did before).  Each run's own wall time
(``summary.json``'s ``wall_seconds``: the time loop, without start-up) is reported, and each
loaded run's ratio to the alone time.  The target: each of two side-by-side runs takes at
most about 2.2 times its alone time.

Usage::

    .venv/bin/python benchmarks/bench_shared.py [--case taylor] [--set KEY=VALUE ...]
        [--rounds 2]

Run it on an otherwise idle machine (it prints the other processes' load before it starts).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(HERE / "src"))

from impactsph.threads import busy_seconds, own_seconds  # noqa: E402


def start(case: str, out: Path, threads: str, sets: list[str]) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "impactsph", "run", case, "-q", "--out", str(out),
           "--set", "output.figures=false", "--set", f"compute.threads={threads}"]
    for s in sets:
        cmd += ["--set", s]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen, out: Path) -> dict:
    _, err = proc.communicate()
    if proc.returncode != 0:
        raise SystemExit(f"run into {out} failed:\n{err[-3000:]}")
    summary = json.loads((out / "summary.json").read_text())
    return {"wall_seconds": summary["wall_seconds"],
            "thread_changes": summary.get("thread_changes", [])}


def load(seconds: float = 2.0) -> float:
    """Cores used by other processes over ``seconds``."""
    b0, o0, t0 = busy_seconds(), own_seconds(), time.monotonic()
    time.sleep(seconds)
    b1, o1, t1 = busy_seconds(), own_seconds(), time.monotonic()
    if b0 is None or b1 is None:
        return float("nan")
    return ((b1 - b0) - (o1 - o0)) / (t1 - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--case", default="taylor")
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    import numba

    most = str(numba.config.NUMBA_NUM_THREADS)
    print(f"case {args.case} {' '.join(args.sets)}; numba threads {most}; other processes' "
          f"load before: {load():.2f} cores", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        k = 0
        for r in range(args.rounds):
            for threads in ("auto", most):
                k += 1
                alone_out = Path(tmp) / f"alone{k}"
                alone = finish(start(args.case, alone_out, threads, args.sets), alone_out)
                outs = [Path(tmp) / f"side{k}a", Path(tmp) / f"side{k}b"]
                procs = [start(args.case, o, threads, args.sets) for o in outs]
                side = [finish(p, o) for p, o in zip(procs, outs, strict=True)]
                row = {"round": r + 1, "threads": threads, "alone_s": alone["wall_seconds"],
                       "side_s": [s["wall_seconds"] for s in side],
                       "ratios": [s["wall_seconds"] / alone["wall_seconds"] for s in side],
                       "changes": [len(s["thread_changes"]) for s in side]}
                hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
                try:
                    time.sleep(1.0)
                    beside_out = Path(tmp) / f"hog{k}"
                    beside = finish(start(args.case, beside_out, threads, args.sets), beside_out)
                finally:
                    hog.kill()
                    hog.wait()
                row["beside_busy_loop_s"] = beside["wall_seconds"]
                row["beside_busy_loop_ratio"] = beside["wall_seconds"] / alone["wall_seconds"]
                rows.append(row)
                print(f"round {r + 1} threads={threads:>4}: alone {row['alone_s']:.2f} s; side "
                      f"by side {row['side_s'][0]:.2f} s and {row['side_s'][1]:.2f} s "
                      f"(x{row['ratios'][0]:.2f}, x{row['ratios'][1]:.2f}); beside a busy loop "
                      f"{beside['wall_seconds']:.2f} s (x{row['beside_busy_loop_ratio']:.2f}); "
                      f"thread changes {row['changes']}", flush=True)
    print(json.dumps(rows))
    if os.environ.get("BENCH_JSON"):
        Path(os.environ["BENCH_JSON"]).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
