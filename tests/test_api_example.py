"""``examples/api_example.py``, the tour of the Python API, runs and writes a full run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).parents[1] / "examples" / "api_example.py"


def test_api_example_runs(tmp_path):
    out = tmp_path / "api"
    env = {**os.environ, "IMPACTSPH_EXAMPLE_OUT": str(out)}
    # it takes under a minute; the limit leaves room for a busy machine
    res = subprocess.run([sys.executable, str(EXAMPLE)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    for text in ("Simulation: ", "recorded ", "velocity (n, dim)", "density (n,)",
                 "deviatoric_stress (n, 3, 3)", "summary keys: ", "contact_time_us = "):
        assert text in res.stdout, res.stdout
    for name in ("case.json", "history.csv", "probes.csv", "snapshots.npz", "summary.json",
                 "velocity_profile.png", "mid_velocity.png", "kinetic_energy.png"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["t_end"] == 8e-6 and summary["n_particles"] == 202
    assert not (tmp_path / "runs").exists()  # the output went where it was told


def test_api_example_takes_out_argument(tmp_path):
    res = subprocess.run([sys.executable, str(EXAMPLE), "--help"], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0 and "--out" in res.stdout
