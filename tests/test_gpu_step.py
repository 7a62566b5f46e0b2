"""The whole step on the device (:mod:`impactsph.gpu_step`) against the CPU: the runs of
``tests/test_gpu.py``'s :data:`RESIDENT` table, computed by that file's worker (in numba's CUDA
simulator in CI; on a GPU too where one is present).  A file of its own so that the test
session's workers run it beside ``tests/test_gpu.py``'s other simulator runs."""

from __future__ import annotations

import numpy as np
import pytest
from test_gpu import (
    HOST_PATH,
    MODES,
    RESIDENT,
    TOL,
    _enforce_input,
    _relative_errors,
    _resident_run,
    _run_worker,
    _skip_without_gpu,
    _survey_input,
)

#: The device against the CPU with records in float32: the passes do the arithmetic between
#: two record values in float32 (numba's typing: float32 with float32 is float32), whose
#: epsilon is 1.2e-7, and the CPU's vectorised loops order those operations otherwise than a
#: GPU thread does (and numba's CUDA simulator follows numpy's scalar rules, in which a Python
#: float does not widen a float32).  Measured after the Taylor bar's 5 steps: 5e-8 of the
#: largest velocity and energy, 2.5e-10 of the positions.
FLOAT32_TOL = 1e-6


@pytest.fixture(scope="module", params=MODES)
def resident_comparison(request, tmp_path_factory):
    """The :data:`RESIDENT` runs with the state on the device (the worker) and on the CPU."""
    mode = request.param
    _skip_without_gpu(mode)
    folder = tmp_path_factory.mktemp(f"resident-{mode}")
    report = _run_worker(mode, "resident", folder)
    cpu = {name: _resident_run(name, on_gpu=False) for name in (*RESIDENT, *HOST_PATH)}
    return mode, report, cpu, folder


def test_the_simulator_polls_without_holding_the_interpreter(resident_comparison):
    """The resident step's reductions (shared memory and barriers) run on the simulator's
    threads, whose poll releases the interpreter lock (``test_gpu._yielding_simulator``;
    without it the resident runs take twice as long); its other kernels' blocks run their
    threads in turn (``test_gpu._sequential_simulator``): a numba whose simulator no longer
    has ``BlockThread``, or no longer polls through its ``is_alive``, fails here, not by a
    slow test run."""
    mode, report, _, _ = resident_comparison
    assert report["yielding"] == report["sequential"] == (mode == "simulator")
    if mode == "simulator":
        assert report["polls"] > 1000, report["polls"]
        assert report["blocks_in_turn"] > 1000, report["blocks_in_turn"]


@pytest.mark.parametrize("name", list(RESIDENT))
def test_the_whole_step_on_the_device_matches_the_cpu(resident_comparison, name):
    """With the state kept on the device (neighbour list built there, the integrator's stages,
    the survey and the books on the device) the final state, every history column, the
    probes, the counts of pairs, evaluations and rebuilds and each particle's neighbours (in
    their order, but for the CPU's inner entries, its rows' first) are the CPU run's, to
    1e-10 (with records in float32, to 1e-6: :data:`FLOAT32_TOL`); the callback's change
    reached the device."""
    mode, report, cpu, folder = resident_comparison
    sim, _, lists = cpu[name]
    tol = FLOAT32_TOL if "float32" in name else TOL
    info = report[name]
    assert info["resident"] and info["device"] == "gpu"
    # the first evaluation's copies on the host path were let go (45% of the device memory
    # in 3D) and nothing allocated them again
    assert info["host_path_arrays"] == [], info["host_path_arrays"]
    with np.load(folder / f"{name}.npz") as z:
        errors = _relative_errors(sim.state.arrays(), {k: z[k] for k in z.files})
    assert not {k: e for k, e in errors.items() if not e <= tol}, (mode, name, errors)
    history = sim.record.history
    assert len(info["history"]) == len(history)
    for key in history[0]:
        ref = np.array([row[key] for row in history])
        got = np.array([row[key] for row in info["history"]])
        # a vector's components against the vector's size (a component that is zero on the
        # CPU may be round-off on the device)
        like = [k for k in history[0] if k[:-2] == key[:-2]] if key[-2:] in ("_x", "_y", "_z") \
            else [key]
        scale = max(float(np.abs([row[k] for row in history for k in like]).max()), 1e-300)
        assert np.abs(got - ref).max() <= tol * scale + 1e-18, (name, key, ref, got)
    books = [sim.viscous_dissipation, sim.correction_work, sim.correction_heating,
             *sim.wall_impulse.tolist(), sim.integrator.constraint_events]
    np.testing.assert_allclose(info["books"], books, rtol=tol,
                               atol=tol * float(np.abs(books).max()))  # (a zero component)
    if not (len(sim.walls) or sim.problem.body_names[1:]):  # no walls' push: none booked
        assert not any(info["books"][3:-1])
    # the state came down only for the callback's read (step 2) and at the end of the run:
    # history rows, probes and the survey read the device
    assert info["downloads"] == 2, info["downloads"]
    if mode == "simulator":  # on a GPU, fused multiply-adds may move a pair at the radius
        assert info["counts"] == [sim.solver.pair_evaluations, sim.solver.rate_evaluations,
                                  sim.solver.neighbours.builds]
        # the device's rows are the CPU's, but for the CPU's inner entries, which the CPU
        # holds first (neighbours.py) and the device, which keeps no inner list, in place
        assert len(info["lists"]) == len(lists)
        assert any(inner for inner, _ in lists) == (sim.solver.neighbours.inner_ends is not None)
        for (_, got), (inner, row) in zip(info["lists"], lists, strict=True):
            near = set(row[:inner])
            assert [q for q in got if q in near] + [q for q in got if q not in near] == row
    if name == "block-3d":  # rows split at the support (neighbours.py) in the lists compared
        nl = sim.solver.neighbours
        assert np.any(nl.splits < nl.offsets[1:])
    if name == "rings-2d":  # rebuilt on the device at nearly every evaluation
        assert info["counts"][2] > RESIDENT[name][2]
    if name == "bars-1d":  # a probe's rows, taken from the device at every step
        assert sum(len(rows) for rows in sim.record.probes.values()) > RESIDENT[name][2]
    # a gauge's rows, taken from the device at every step (no download): every field
    assert len(info["gauges"]) == len(sim.record.gauges)
    if sim.record.gauges:
        ref, got = np.array(sim.record.gauges), np.array(info["gauges"])
        scale = np.maximum(np.abs(ref).max(axis=0), 1e-300)  # (each column against its own)
        assert (np.abs(got - ref) <= tol * scale + 1e-18).all(), (name, ref, got)
    if name == "taylor-2d":
        assert len(sim.record.gauges) == RESIDENT[name][2] + 1
    if name == "taylor-2d-half-stretch":  # h set on the device at its rebuilds
        assert info["counts"][2] > 2 and sim.state.smoothing_length.max() > 1.1 * float(
            sim.solver._h_reference.max())
    if name == "taylor-2d-layer":  # a symmetry plane's corner images; clamped particles
        assert sim.state.clamped.any() and np.any(sim.integrator.clamp_impulse != 0.0)
    for probe, rows in sim.record.probes.items():
        got = info["probes"][probe]
        assert [t for t, _ in got] == [t for t, _ in rows]
        np.testing.assert_allclose([v for _, v in got], [v for _, v in rows], rtol=1e-10,
                                   atol=1e-12)


@pytest.mark.parametrize("name", list(RESIDENT))
def test_the_device_memory_is_counted_from_the_runs_sizes(resident_comparison, name):
    """:mod:`impactsph.gpu_memory` counts a device run's arrays from its sizes (particles,
    ghosts, list entries, cells) to within 1% of what the run holds (each allocation once,
    the summary's ``device_memory_bytes``), and reads the layout it counts from the case as
    the run has it: what the preflight's GPU memory estimate stands on.  (The 1%: a kept
    buffer holds the largest size an earlier build asked for.)"""
    mode, report, cpu, folder = resident_comparison
    memory = report[name]["memory"]
    held = sum(size for size, _ in memory["allocated"])
    counted = sum(memory["parts"].values())
    assert memory["summary"] == held
    assert memory["case_layout"] == memory["layout"]
    assert abs(counted / held - 1.0) < 0.01, (name, held, counted, memory["parts"],
                                               memory["allocated"][:16])


def test_a_gpu_out_of_memory_in_a_step_stops_the_run_in_one_line(resident_comparison):
    """An allocation the GPU refuses in a step (a rebuild's buffers) stops the run with a
    :class:`~impactsph.errors.DeviceMemoryError`: one line that says in which step and at
    what time, and what the run held on the GPU; the record keeps it as the failure and the
    history keeps every whole step's row (``taylor-2d`` writes one a step)."""
    mode, report, cpu, folder = resident_comparison
    info = report["out_of_memory"]
    error = info["error"]
    assert error is not None, info
    assert error.startswith(f"the GPU ran out of memory in step {info['step'] + 1}, at t = "), error
    assert "; the run held " in error and " neighbour-list entries" in error, error
    assert error.endswith('compute.device = "cpu"') and "\n" not in error, error
    assert info["failure"] == error
    assert info["rows"] == info["step"] + 1 and info["step"] >= 1, info


def test_a_symmetry_plane_on_the_host_path_matches_the_cpu(resident_comparison):
    """With the state on the host (``compute.resident = false``) and the rates on the
    device, a symmetry plane's ghosts take their sources' results mirrored on the host, on the
    records copied down and back up: the half Taylor bar's final state is the CPU's."""
    mode, report, cpu, folder = resident_comparison
    name = "taylor-2d-half-host"
    sim = cpu[name][0]
    assert (report[name]["resident"], report[name]["device"]) == (False, "gpu")
    with np.load(folder / f"{name}.npz") as z:
        errors = _relative_errors(sim.state.arrays(), {k: z[k] for k in z.files})
    assert not {k: e for k, e in errors.items() if not e <= TOL}, (mode, errors)


def test_the_host_paths_device_memory_is_counted_from_its_sizes(resident_comparison):
    """The device arrays of a run whose rates alone are on the GPU are
    :meth:`~impactsph.gpu_memory.DeviceLayout.host_path_parts`' count, to within 1%."""
    mode, report, cpu, folder = resident_comparison
    memory = report["taylor-2d-half-host"]["memory"]
    held = sum(size for size, _ in memory["allocated"])
    counted = sum(memory["parts"].values())
    assert abs(counted / held - 1.0) < 0.01, (held, counted, memory["parts"],
                                               memory["allocated"])


def test_a_device_run_restarts_bitwise(resident_comparison):
    """A run with the state on the device (the Taylor bar on its wall), checkpointed after 2
    steps (the state, the device's neighbour list and ghosts downloaded) and continued from
    the checkpoint (uploaded), ends in the uninterrupted run's state, bit for bit."""
    _, report, _, _ = resident_comparison
    restart = report["restart"]
    full = report["taylor-2d"]
    assert restart["resident"] and restart["steps"] == RESIDENT["taylor-2d"][2]
    assert restart["builds_at_checkpoint"] > 1  # a list built on the device, checkpointed
    assert not any(restart["differences"].values()), restart["differences"]
    assert restart["books"] == full["books"][:-1]
    assert restart["last_row"] == full["history"][-1]
    assert restart["counts"] == full["counts"][::2]


def test_the_device_prefix_sum_spans_several_chunks(resident_comparison):
    """The device's prefix sum (its chunks, their totals' sum, the recursion) equals numpy's
    cumulative sum at 1, 255, 257 and 65,836 entries."""
    _, report, _, _ = resident_comparison
    assert all(report["scans"].values()), report["scans"]


def test_the_walls_constraint_on_the_device_is_the_cpus(resident_comparison):
    """The device's walls' constraint (particles behind two walls put back, their velocity
    into the wall removed) gives the CPU's positions, velocities, events and impulse."""
    _, report, _, _ = resident_comparison
    x, v, m, walls = _enforce_input()
    moved, impulse = walls.enforce(x, v, m)
    got = report["enforce"]
    assert moved > 5 and got["events"] == moved
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got["v"], v, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got["impulse"], impulse, rtol=1e-12)


@pytest.mark.parametrize("spoil", [False, True])
def test_the_survey_on_the_device_is_the_cpus(resident_comparison, spoil):
    """The device's survey (each particle's part the CPU's ``survey_particle``) gives the CPU
    survey's step, energies and momentum, and its first bad value: the first particle behind
    a wall (its last kind), or with particle 30's energy NaN and 35's stress infinite, the
    energy (its code ``3 n + 30`` is the smallest)."""
    from impactsph.integrate import _survey_kernel

    _, report, _, _ = resident_comparison
    x, v, rho, e, S, m, h, material, table, walls = _survey_input(spoil)
    n = x.shape[0]
    dt, sums, bad = _survey_kernel(2)(n, x, v, rho, e, S, m, m, h, material, table,
                                      0.3, 0.0, walls.points, walls.normals)
    got_dt, got_sums, got_bad = report["survey"][str(spoil)]
    behind = np.flatnonzero(walls.distances(x).min(axis=1) < 0.0)
    assert bad == got_bad == (3 * n + 30 if spoil else 6 * n + behind[0])
    np.testing.assert_allclose(got_dt, dt, rtol=1e-14)
    np.testing.assert_allclose(got_sums, sums, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(sums)))
