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

The threaded passes run in two child processes, on a cache of their own: the first compiles
them, the second loads them from numba's cache, and each must give the serial passes' run to
the bit.  A ``prange`` loop is two codes: numba links a copy of its body into the pass and
optimises it again, the compiling process runs the first and the cache holds the second, and
where the pass reassociates (the vectorised neighbour loops) the copies rounded otherwise: a
density 1 ulp apart after 10 steps of the 3D block, the 1D bars and the Balsara bars likewise
(2026-12-05).  Those passes now run in shares of their chunks on numba's threads
(:mod:`impactsph.physics.chunked`).  Run in one process, as this test once was, it compared
the serial passes with whichever copy the suite's cache happened to hold.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

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
    # the 1D bars with Balsara's switch (vectorised, reassociating): the 1D pair pass and the
    # switch pass
    "bars-balsara": ("bars", ['viscosity={scheme="balsara"}', "analysis=none",
                              "time.max_steps=80"],
                     {"particle_pass", "pair_pass", "switch_pass", "stage"}),
}
PASSES = ("particle_pass", "moment_pass", "gradient_pass", "pair_pass", "correction_pass",
          "switch_pass",
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


def _serial_run(case: str, overrides: list[str], monkeypatch) -> Simulation:
    """The case run here on the serial passes (the threaded ones run in child processes,
    :func:`_child_run`)."""
    monkeypatch.setenv(PARALLEL_VARIABLE, "0")
    sim = Simulation(load_case(case, overrides))
    assert sim.solver.backend.options.parallel is False
    sim.run()
    return sim


def _child_run(name: str, out: str) -> None:
    """In a child process: the case run on the threaded passes; its state arrays to ``out``
    (.npz) and, beside it (.json), its steps, neighbour-list builds, and for each pass it ran
    whether numba compiled it here or loaded it from its cache."""
    import numba

    case, overrides, _ = CASES[name]
    before = _used(True)
    # (two threads throughout: "auto" would drop to one on a loaded machine)
    sim = Simulation(load_case(case, [*overrides, "compute.threads=2"]))
    assert sim.solver.backend.options.parallel is True and numba.get_num_threads() == 2
    sim.run()
    how = {}
    for module_name, p in _used(True) - before:
        stats = getattr(sys.modules[module_name], p).stats
        loaded = sum(stats.cache_hits.values()) and not sum(stats.cache_misses.values())
        how[p] = "loaded" if loaded else "compiled"
    np.savez(out, **sim.state.arrays())
    Path(out).with_suffix(".json").write_text(json.dumps(
        {"step": sim.state.step, "builds": sim.solver.neighbours.builds, "passes": how}))


def _threaded_in_a_child(name: str, cache: Path, out: Path) -> tuple[dict, dict]:
    # two threads: the chunked passes run in two shares, called at their addresses
    # (impactsph.physics.chunked), whatever the worker's own count
    env = dict(os.environ, **{PARALLEL_VARIABLE: "1", "IMPACTSPH_CACHE_DIR": str(cache),
                              "NUMBA_NUM_THREADS": "2"})
    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
              f"from test_parallel_passes import _child_run; _child_run({name!r}, {str(out)!r})")
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=1200)
    assert result.returncode == 0, result.stderr[-3000:]
    with np.load(out) as arrays:
        return dict(arrays), json.loads(out.with_suffix(".json").read_text())


@pytest.mark.parametrize("name", list(CASES))
def test_serial_passes_give_the_parallel_passes_run_to_the_bit(name, monkeypatch, tmp_path):
    case, overrides, passes = CASES[name]
    serial = _serial_run(case, overrides, monkeypatch)
    kept = serial.state.arrays()
    start = Simulation(load_case(case, overrides)).state.arrays()
    assert not np.array_equal(kept["velocity"], start["velocity"])  # the run did something
    # the threaded passes compiled in one child, then loaded from the cache it wrote in another
    for expected in ("compiled", "loaded"):
        ran, info = _threaded_in_a_child(name, tmp_path / "cache", tmp_path / f"{expected}.npz")
        assert passes <= set(info["passes"]), f"{name}: {sorted(passes)} not all threaded"
        assert {p: info["passes"][p] for p in passes} == dict.fromkeys(passes, expected)
        assert info["step"] == serial.state.step > 0
        assert info["builds"] == serial.solver.neighbours.builds
        assert ran.keys() == kept.keys()
        different = [key for key in ran if not np.array_equal(ran[key], kept[key])]
        assert not different, (f"{name}: {different} differ between the serial passes and the "
                               f"threaded ones {expected} (physics/chunked.py)")


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
