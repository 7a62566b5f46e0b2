"""Running a benchmark script's worker in another source tree: shared by the scripts that
time this tree beside others (``--trees``), alternating round by round."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any


def worker_result(script: str | Path, tree: Path, args: list[str], threads: int,
                  **env: str) -> dict[str, Any]:
    """``python SCRIPT --worker ARGS`` with ``TREE/src`` as its impactsph
    (``PYTHONPATH``) and ``threads`` numba threads (``env``: more variables, each kept where
    the caller's environment has it already): the JSON of its last line of output."""
    environ = dict(os.environ, PYTHONPATH=str(Path(tree) / "src"),
                   NUMBA_NUM_THREADS=str(threads))
    for name, value in env.items():
        environ.setdefault(name, value)
    out = subprocess.run([sys.executable, str(script), "--worker", *args], env=environ,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def alternated(script: str | Path, trees: list[Path], keys: list[Any], worker_args,
               rounds: int, threads: int, **env: str) -> dict[tuple[str, Any], list[dict]]:
    """:func:`worker_result` of each tree for each key, ``rounds`` times, the trees
    alternating within each key and round (so that a busy spell falls on all of them):
    ``{(str(tree), key): [one result a round]}``; ``worker_args(key)`` gives the worker's
    arguments."""
    results: dict[tuple[str, Any], list[dict]] = {}
    for _ in range(rounds):
        for key in keys:
            for tree in trees:
                results.setdefault((str(tree), key), []).append(
                    worker_result(script, tree, worker_args(key), threads, **env))
    return results
