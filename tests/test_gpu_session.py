"""``benchmarks/gpu_session.sh`` keeps to the time its call has (``TOTAL``): run here with a
stand-in ``python3`` that records its arguments and returns at once (no GPU, no numba-cuda
needed), a stage whose time limit would pass ``TOTAL`` is skipped and named in the session
log, the others run in their order, and the tests' limit ends before ``TOTAL``."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "gpu_session.sh"

STAND_IN = """#!/bin/sh
echo "$*" >> "{calls}"
"""


def _session(tmp_path: Path, **env: str) -> tuple[str, list[str]]:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    calls = tmp_path / "calls.txt"
    python = bin_dir / "python3"
    python.write_text(STAND_IN.format(calls=calls))
    python.chmod(0o755)
    out = tmp_path / "out"
    run_env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
                   OUT=str(out), KERNELS="0", **env)
    done = subprocess.run(["bash", str(SCRIPT)], cwd=ROOT, env=run_env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    log = (out / "session.log").read_text()
    return log, calls.read_text().splitlines() if calls.exists() else []


@pytest.mark.skipif(shutil.which("bash") is None or shutil.which("timeout") is None,
                    reason="needs bash and coreutils' timeout")
def test_a_stage_that_would_pass_the_calls_total_is_skipped_and_named(tmp_path):
    log, calls = _session(tmp_path, TOTAL="200")
    # the main table's limit (GPU_BUDGET 240 + 40) cannot end within 200 s: skipped, said so
    assert "skipped: the whole step on the GPU" in log and "(a limit of 280 s;" in log
    assert not any("--sizes 1e5 1e6 1e7" in c for c in calls)
    # the next stages (limits of 100 s) fit, and ran in their order
    float32 = next(k for k, c in enumerate(calls) if "--record-precision float32" in c)
    cells = next(k for k, c in enumerate(calls) if "--particle-order cells" in c)
    assert float32 < cells
    assert "--dims 3 --sizes 1e6" in calls[float32]
    # the tests' limit is cut to end 20 s before TOTAL
    limit = int(log.split("tests on the GPU (in the background, at most ")[1].split(" s)")[0])
    assert limit <= 180


@pytest.mark.skipif(shutil.which("bash") is None or shutil.which("timeout") is None,
                    reason="needs bash and coreutils' timeout")
def test_with_the_default_total_the_main_table_runs(tmp_path):
    log, calls = _session(tmp_path, PRECISION="0", ORDER="0", FEATURES="0", HOST_STAGES="0")
    assert "skipped" not in log
    assert sum("--sizes 1e5 1e6 1e7" in c for c in calls) == 1
    assert not any("--record-precision float32" in c or "--particle-order" in c
                   for c in calls)
