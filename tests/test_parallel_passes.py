"""The generated passes compiled with numba's parallel transform (the default) and without it
(``$IMPACTSPH_PARALLEL=0``, which the rest of this suite runs: tests/conftest.py) give the
same run to the bit.

Each case runs a few dozen steps in both modules in this process, and every state array must
be equal.  Between them, and with test_threads' Taylor bar (AC: the correction pass), the
cases call every pass of the template (:mod:`impactsph.physics.passes`) that the serial
modules compile serial: the particle pass, the moment pass (the kernel gradient correction of
the forces), the gradient pass (the reconstructed velocity jump), the pair pass in 2D and 3D,
the correction pass, the friction pass (two bodies, Coulomb friction), the hourglass pass and
the stage.  The switch pass stays threaded in both (physics/passes.py: its reassociated sums
came out in another order compiled serial, a difference of 6e-15 in Balsara's factor after 40
steps, which this test found).  The threads' side (one thread against two, and both against
the serial passes, in a process of two threads) is
``tests/test_threads.py::test_results_do_not_depend_on_the_thread_count``.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from impactsph.loading import load_case
from impactsph.output import provenance
from impactsph.physics.options import PARALLEL_VARIABLE, PassOptions, parallel_default
from impactsph.simulation import Simulation

CASES = {
    # 3D on a wall's ghosts, with the kernel gradient correction of the forces and the
    # hourglass control: the particle, moment, pair (3D) and hourglass passes and the stage
    "block-3d-stabilised": ("taylor", [
        "dimension=3", "analysis=none", "bodies.0.velocity=[0.0, 0.0, -200.0]",
        "bodies.0.geometry.origin=[-0.0015, -0.0015, 0.0]",
        "bodies.0.geometry.size=[0.003, 0.003, 0.00375]", "bodies.0.geometry.count=[4, 4, 5]",
        "boundaries.0.point=[0.0, 0.0, 0.0]", "boundaries.0.normal=[0.0, 0.0, 1.0]",
        "stabilisation.gradient_correction=velocity_gradient_and_forces",
        "stabilisation.hourglass=1.0", 'viscosity={scheme="av"}', "time.max_steps=30"],
        {"particle_pass", "moment_pass", "pair_pass", "hourglass_pass", "stage"}),
    # two rings that touch within the run, with friction between them, the artificial stress
    # and the reconstructed velocity jump: the friction and gradient passes, the 2D pair pass
    # and the stage
    "rings-friction-reconstruction": ("rings", [
        "bodies.0.geometry.spacing=0.004", "bodies.1.geometry.spacing=0.004",
        "bodies.0.geometry.centre=[-0.0405, 0.0]", "bodies.1.geometry.centre=[0.0405, 0.0]",
        "analysis=none", "contact.friction=0.2", 'viscosity={scheme="reconstruction"}',
        "time.max_steps=60"],
        {"particle_pass", "pair_pass", "friction_pass", "gradient_pass", "stage"}),
}
PASSES = ("particle_pass", "moment_pass", "gradient_pass", "pair_pass", "correction_pass",
          "friction_pass", "hourglass_pass", "stage")


def _used(parallel: bool) -> set[tuple[str, str]]:
    """(module, pass) of the generated CPU modules of this kind that hold machine code."""
    used = set()
    for name, module in list(sys.modules.items()):
        generated = name.startswith("impactsph_generated.") and not name.endswith("_simulated")
        if not generated or ("_serial_" in name) == parallel:
            continue
        for p in PASSES:
            if getattr(getattr(module, p, None), "overloads", None):
                used.add((name, p))
    return used


def _run(case: str, overrides: list[str], parallel: bool, monkeypatch):
    monkeypatch.setenv(PARALLEL_VARIABLE, "1" if parallel else "0")
    before = _used(parallel)
    sim = Simulation(load_case(case, overrides))
    assert sim.solver.backend.options.parallel is parallel
    sim.run()
    newly = {p for _, p in _used(parallel) - before}
    return sim, newly


@pytest.mark.parametrize("name", list(CASES))
def test_serial_passes_give_the_parallel_passes_run_to_the_bit(name, monkeypatch):
    case, overrides, passes = CASES[name]
    parallel, used = _run(case, overrides, True, monkeypatch)
    serial, _ = _run(case, overrides, False, monkeypatch)
    assert passes <= used, f"{name}: {sorted(passes - used)} did not run in the parallel passes"
    assert parallel.state.step == serial.state.step > 0
    assert parallel.solver.neighbours.builds == serial.solver.neighbours.builds
    start = Simulation(load_case(case, overrides)).state.arrays()
    ran, kept = parallel.state.arrays(), serial.state.arrays()
    assert ran.keys() == kept.keys()
    assert not np.array_equal(ran["velocity"], start["velocity"])  # the run did something
    different = [key for key in ran if not np.array_equal(ran[key], kept[key])]
    assert not different, f"{name}: {different} differ between the parallel and serial passes"


def test_the_environment_chooses_and_bad_values_are_named(monkeypatch):
    import numba

    monkeypatch.delenv(PARALLEL_VARIABLE, raising=False)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    assert parallel_default() is True and PassOptions().parallel is True
    assert provenance()["parallel_passes"] is True
    # unset, a process whose numba has one thread compiles the serial passes: the threaded
    # ones could only cost it compile time; the variable still decides where it is set
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    assert parallel_default() is False and PassOptions().tag.endswith("_serial")
    monkeypatch.setenv(PARALLEL_VARIABLE, "")
    assert parallel_default() is False
    monkeypatch.setenv(PARALLEL_VARIABLE, "1")
    assert parallel_default() is True and PassOptions().parallel is True
    monkeypatch.setenv(PARALLEL_VARIABLE, "0")
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)
    assert PassOptions().parallel is False and PassOptions().tag.endswith("_serial")
    assert provenance()["parallel_passes"] is False  # every output records which
    monkeypatch.setenv(PARALLEL_VARIABLE, "yes")
    with pytest.raises(ValueError, match=r"\$IMPACTSPH_PARALLEL = 'yes': allowed are 1 .* and 0"):
        PassOptions()


def test_the_command_line_refuses_a_bad_value_in_one_line_before_any_work(monkeypatch, tmp_path):
    from typer.testing import CliRunner

    from impactsph.cli import app

    monkeypatch.setenv(PARALLEL_VARIABLE, "2")
    res = CliRunner().invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "$IMPACTSPH_PARALLEL = '2'" in lines[0], res.output
    assert not (tmp_path / "x").exists()
