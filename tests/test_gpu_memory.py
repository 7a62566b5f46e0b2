"""The GPU memory estimate before a run (:mod:`impactsph.gpu_memory`, the preflight's GPU
line and refusal), without a GPU: the GPU's free memory and the device choice are stood in
for.  The count itself is held to a device run's allocations in numba's CUDA simulator by
``tests/test_gpu_step.py`` (``test_the_device_memory_is_counted_from_the_runs_sizes``)."""

from __future__ import annotations

import csv
import json

import pytest
from test_preflight import _toml
from typer.testing import CliRunner

from impactsph import gpu
from impactsph import preflight as pf
from impactsph.cli import app
from impactsph.gpu_memory import DeviceLayout
from impactsph.loading import load_case, validate_case
from impactsph.physics.options import PassOptions
from impactsph.physics.rates import compiled_passes
from impactsph.problem import build_problem

runner = CliRunner()


def lattice(count: list[int], **compute) -> dict:
    """A steel block of ``count`` particles (2D or 3D, 1 mm apart), falling at 100 m/s."""
    dim = len(count)
    return {"name": "lattice", "dimension": dim,
            "materials": {"steel": {"model": "elastic", "density": 7850.0,
                                    "youngs_modulus": 2e11}},
            "bodies": [{"name": "block", "material": "steel",
                        "velocity": [0.0] * (dim - 1) + [-100.0],
                        "geometry": {"origin": [0.0] * dim,
                                     "size": [1e-3 * c for c in count], "count": count}}],
            "time": {"end": 1e-6}, "compute": {"device": "gpu", **compute}}


@pytest.fixture
def a_gpu(monkeypatch):
    """A GPU with ``free[0]`` bytes free, that the case's run would keep its state on."""
    free = [80e9]
    monkeypatch.setattr(gpu, "unavailable_reason", lambda: None)
    monkeypatch.setattr(gpu, "free_memory", lambda: (int(free[0]), "Test GPU"))
    monkeypatch.setattr(gpu, "launch_settings", lambda environ=None: (128, 0))
    monkeypatch.setattr(gpu, "simulator_enabled", lambda: False)
    return free


@pytest.mark.parametrize("options", [
    PassOptions(), PassOptions(gradient_correction="velocity_gradient_and_forces",
                               viscosity_factor=True),
    PassOptions(axisymmetric=True, compatible_energy=True, record_precision="float32"),
    PassOptions(artificial_stress=0.3, velocity_reconstruction=True)])
def test_the_record_layout_is_the_compiled_passes(options):
    """``PassOptions.record_layout`` gives the columns of the module compiled with the
    options (the module is generated and imported; nothing is compiled)."""
    for dim in (2,) if options.axisymmetric else (1, 2, 3):
        passes = compiled_passes(dim, False, options)
        layout = options.record_layout(dim)
        assert (layout["columns"], layout["u"]) == (passes.RECORD_COLUMNS, passes.U), dim


def test_a_gpu_run_that_does_not_fit_is_refused_before_its_particles_are_placed(
        a_gpu, tmp_path, monkeypatch):
    """``impactsph check`` and ``impactsph run`` refuse it with one line that names the field
    that sets the particle count, the estimate, the GPU and its free memory, before any
    particle is placed (4e7 particles: placing them would take minutes)."""
    a_gpu[0] = 2e9
    monkeypatch.setattr(pf, "available_memory", lambda: int(1e12))  # (the host's is enough)
    path = tmp_path / "big.toml"
    path.write_text(_toml(lattice([400, 400, 250])))
    for command in (["check", str(path)], ["run", str(path), "--quiet", "--out",
                                           str(tmp_path / "out")]):
        res = runner.invoke(app, command)
        assert res.exit_code == 2, res.output
        lines = res.output.strip().splitlines()
        assert len(lines) == 1, res.output
        assert lines[0].startswith("error: bodies.0.geometry.count = [400, 400, 250]: the run "
                                   "needs about "), lines[0]
        assert "of GPU memory (an estimate: 40,000,000 particles" in lines[0], lines[0]
        assert "the Test GPU has 2 GB free" in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


def test_a_gpu_run_that_fits_says_its_estimate_and_the_gpus_free_memory(a_gpu):
    case = validate_case(lattice([20, 20, 10]))
    report = pf.preflight(case)
    assert report.errors == []
    est = report.estimate
    line = next(x for x in report.lines() if x.startswith("estimated GPU memory: "))
    assert line.endswith("of 80 GB free on the Test GPU"), line
    assert "device: the GPU, the whole step there (the state stays on it)" in report.lines()
    # what it stands on: the layout's arrays for the placed particles and their list, the
    # list's indices once more (a rebuild that outgrows them), the margin and the base
    layout = DeviceLayout.of_case(case)
    n = est.total
    entries = n * est.neighbours
    arrays = layout.bytes(n, 0, entries, 0) + 4 * entries
    # (the cells and the material table, a few kB, are left out here)
    assert est.device_memory - pf.GPU_BASE_MEMORY == pytest.approx(
        pf.GPU_MEMORY_SAFETY * arrays, rel=1e-3)
    # the host holds neither the step's start copy nor the records of a run on the GPU
    cpu = lattice([20, 20, 10])
    cpu["compute"] = {"device": "cpu"}
    assert est.memory < pf.preflight(validate_case(cpu)).estimate.memory


def test_the_gpu_estimate_grows_with_what_the_case_switches_on(a_gpu):
    """Per particle, the estimate's arrays grow with the dimension, a wall's ghosts, SSP-RK3
    (a second start copy), the compatible update (the work pass's outputs) and float32
    records shrink it: each where the device run allocates for it."""
    def per_particle(case: dict) -> float:
        c = validate_case(case)
        est = pf.estimate(c, pf.count_particles(c))
        return (est.device_memory - pf.GPU_BASE_MEMORY) / est.total

    base = lattice([40, 40, 40])
    flat = per_particle(lattice([200, 200]))
    plain = per_particle(base)
    walled = per_particle({**base, "boundaries": [{"type": "wall", "point": [0.0, 0.0, 0.0],
                                                   "normal": [0.0, 0.0, 1.0]}]})
    ssp = per_particle({**base, "time": {"end": 1e-6, "integrator": "ssp_rk3"}})
    compatible = per_particle({**base, "time": {"end": 1e-6, "energy_update": "compatible"}})
    float32 = per_particle(lattice([40, 40, 40], record_precision="float32"))
    assert flat < plain < walled
    assert plain < ssp and plain < compatible
    assert float32 < plain


def test_a_run_with_its_rates_alone_on_the_gpu_is_estimated_and_a_cpu_run_is_not(a_gpu):
    """The host path (``compute.resident = false``) holds the rates' arrays alone
    (:meth:`~impactsph.gpu_memory.DeviceLayout.host_path_parts`, held to a run's in
    ``tests/test_gpu_step.py``), and is refused in its own words where they do not fit."""
    host = pf.preflight(validate_case(lattice([10, 10], resident=False)))
    assert ("device: the GPU for the rates, the state on the host between steps "
            "(compute.resident = false: copied to the GPU at each evaluation)") in host.lines()
    case = validate_case(lattice([10, 10], resident=False))
    est = host.estimate
    layout = DeviceLayout.of_case(case)
    entries = est.total * est.neighbours
    table = int(build_problem(case).table.nbytes)
    arrays = sum(layout.host_path_parts(est.total, 0, entries, table_bytes=table).values()) \
        + 4 * entries
    assert est.device_memory - pf.GPU_BASE_MEMORY == pytest.approx(
        pf.GPU_MEMORY_SAFETY * arrays, rel=1e-3)
    a_gpu[0] = 1e8
    refusal = pf.preflight(validate_case(lattice([1000, 1000], resident=False))).errors
    assert [f.field for f in refusal] == ["bodies.0.geometry.count"]
    assert "(an estimate: 1,000,000 particles, their rates on the GPU)" in refusal[0].message
    cpu = lattice([10, 10])
    cpu["compute"] = {"device": "cpu"}
    report = pf.preflight(validate_case(cpu))
    assert report.estimate.device_memory is None
    assert not any("GPU" in x for x in report.lines())


def test_without_a_gpu_the_case_is_not_counted_on_one():
    """Here (no GPU, or numba's CUDA simulator): a GPU case runs on the CPU, which the
    preflight says, and nothing is estimated or refused for a GPU."""
    if gpu.unavailable_reason() is None:
        pytest.skip("a GPU is here")
    case = load_case("taylor", ['compute.device="gpu"'])
    assert not pf.device_plan(case).resident
    report = pf.preflight(case)
    assert report.estimate.device_memory is None
    assert (f"device: compute.device = 'gpu' but {gpu.unavailable_reason()}; the run will use "
            f"the CPU") in report.lines()


class CudaAPIError(Exception):
    """numba-cuda's driver error, as its refusal of an allocation reads."""

    def __init__(self, code: int, message: str):
        super().__init__(f"[{code}] {message}")
        self.code = code


def test_a_run_out_of_gpu_memory_stops_in_one_line_and_keeps_its_outputs(tmp_path,
                                                                          monkeypatch):
    """Where the GPU refuses an allocation in a step, ``impactsph run`` stops with one line
    (exit code 3) that says in which step and when, and keeps the history of every whole
    step and a summary whose status is ``out_of_memory`` (the refusal stood in for on the
    CPU: the same run with the state on the device, in the simulator, is
    ``tests/test_gpu_step.py``'s)."""
    from impactsph.integrate import INTEGRATORS
    from impactsph.simulation import Simulation

    integrator = INTEGRATORS["midpoint"]
    real = integrator.step

    def step(self, state, dt):
        if state.step == 5:
            raise CudaAPIError(2, "Call to cuMemAlloc results in CUDA_ERROR_OUT_OF_MEMORY")
        return real(self, state, dt)

    monkeypatch.setattr(integrator, "step", step)
    monkeypatch.setattr(Simulation, "_on_gpu", lambda self: True)
    monkeypatch.setattr(Simulation, "_keep_on_device", lambda self: None)
    monkeypatch.setattr(gpu, "free_memory", lambda: (int(3e9), "Test GPU"))
    out = tmp_path / "bars"
    res = runner.invoke(app, ["run", "bars", "--out", str(out), "--quiet",
                              "--set", "output.figures=false"])
    assert res.exit_code == 3, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1, res.output
    assert "run stopped: the GPU ran out of memory in step 6, at t = " in lines[0], lines[0]
    assert "the Test GPU has 3 GB free" in lines[0] and str(out) in lines[0], lines[0]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "out_of_memory"
    assert summary["failure"].startswith("the GPU ran out of memory in step 6, at t = ")
    with (out / "history.csv").open() as fh:
        steps = [int(float(row["step"])) for row in csv.DictReader(fh)]
    assert steps[-1] == 5 and steps == sorted(steps), steps
