"""``benchmarks/bench_gpu.py``'s parts that run without a GPU: the comparison with the CPU that
a GPU row carries, and how the parent keeps what a child process wrote before it failed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


def _run_on_the_cpu(bench, n: int, steps: int):
    from bench_rates import make_case

    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    data = make_case(n, 2)
    data["compute"] = {"device": "cpu"}
    sim = Simulation(validate_case(data))
    bench.start_velocities(sim.state)
    dt = stable_time_step(sim.state, sim.problem.table, 0.3)
    for _ in range(steps):
        sim.integrator.step(sim._state, dt)
        sim._survey()
    return make_case(n, 2), dt, {k: np.array(a) for k, a in sim.state.arrays().items()}


def test_the_comparison_is_zero_for_the_same_steps_and_not_for_others(benchmark_script):
    """The CPU's rerun of the same lattice and steps gives the same bits (so a GPU row's
    difference is the GPU's), and one step fewer is seen (so the comparison can fail)."""
    bench = benchmark_script("bench_gpu")
    data, dt, final = _run_on_the_cpu(bench, 400, 3)
    same = bench.difference_to_cpu(final, data, dt, 3)
    assert set(same) >= {"position", "velocity", "density", "deviatoric_stress"}
    assert max(same.values()) == 0.0
    fewer = bench.difference_to_cpu(final, data, dt, 2)
    assert fewer["velocity"] > 1e-3 and fewer["deviatoric_stress"] > 1e-3


@pytest.mark.parametrize("timed_out", [False, True])
def test_a_child_keeps_the_rows_it_wrote(benchmark_script, monkeypatch, timed_out):
    """A child's rows are kept when it fails or is stopped after them; the sizes it did not
    finish say why; the comparison line lands on its size's row; the GPU's launch settings
    go to the child's environment and onto its rows, and so does the records' precision."""
    bench = benchmark_script("bench_gpu")
    row = {"dimension": 3, "n_target": 100, "device_asked": "gpu", "ms_per_step": 1.0}
    stdout = json.dumps(row) + "\n" + json.dumps(
        {"n_target": 100, "relative_difference_to_cpu": {"velocity": 1e-13}}) + "\n"

    seen = {}

    def fake_run(command, **kwargs):
        seen.update(kwargs["env"])
        if timed_out:
            raise subprocess.TimeoutExpired(command, kwargs["timeout"], output=stdout.encode(),
                                            stderr=b"")
        return subprocess.CompletedProcess(command, 1, stdout, "Traceback\nMemoryError: big\n")

    monkeypatch.setattr(bench.subprocess, "run", fake_run)
    rows = bench.child(3, [100, 1000], "gpu", 5, 30.0, compare_cpu=True, launch=(256, 128),
                       precision="float32", model="quarter", order="cells")
    # the launch settings reach the child, and each row says which it ran with
    assert (seen["IMPACTSPH_CUDA_THREADS_PER_BLOCK"], seen["IMPACTSPH_CUDA_MAX_REGISTERS"]) \
        == ("256", "128")
    assert seen[bench.PRECISION_ENV] == "float32"
    assert seen[bench.MODEL_ENV] == "quarter"
    assert seen[bench.ORDER_ENV] == "cells"
    assert all((r["threads_per_block"], r["max_registers"]) == (256, 128) for r in rows)
    assert [r["n_target"] for r in rows] == [100, 1000]
    assert rows[0]["ms_per_step"] == 1.0
    assert rows[0]["relative_difference_to_cpu"] == {"velocity": 1e-13}
    assert rows[1]["error"] == ("timed out after 50 s" if timed_out else "exit 1: MemoryError: big")


@pytest.mark.parametrize("dim", [2, 3])
def test_the_quarter_model_is_the_block_on_a_wall_between_its_planes(benchmark_script, dim):
    """``--model quarter``: the lattice moving onto a rigid wall under it, a symmetry plane
    through each other side at the origin (where the lattice starts), an elastic case's
    stabilisation; a case whose state stays on the device."""
    from bench_rates import make_case

    from impactsph.gpu_step import resident_unsupported
    from impactsph.loading import validate_case

    bench = benchmark_script("bench_gpu")
    lattice = make_case(400, dim)
    case = validate_case(bench.quarter_model(lattice, dim))
    kinds = [b.type for b in case.boundaries]
    assert kinds == ["wall"] + ["symmetry"] * (dim - 1)
    normals = np.array([b.normal for b in case.boundaries])
    assert np.array_equal(np.abs(normals), np.eye(dim)[[dim - 1, *range(dim - 1)]])
    assert all(np.array_equal(b.point, np.zeros(dim)) for b in case.boundaries)
    assert lattice["bodies"][0]["geometry"]["origin"] == [0.0] * dim  # (inside every plane)
    assert case.bodies[0].velocity[-1] == -bench.QUARTER_SPEED
    # "auto", resolved for an elastic case: the kernel gradient correction and the hourglass
    # control
    assert case.stabilisation.gradient_correction != "none" and case.stabilisation.hourglass > 0
    assert resident_unsupported(case) is None
