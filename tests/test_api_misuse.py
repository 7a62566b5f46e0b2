"""The Python API refuses what it cannot do, with one line naming the argument or field, the
value and what it takes, before any step: a new user's audit of the API (2026-12-07) found
these calls silently accepted, or failing with another library's message."""

from __future__ import annotations

import os

import numba as nb
import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.errors import CaseError
from impactsph.models import EOS
from impactsph.models.registry import EquationOfState
from impactsph.runner import run_case

SHORT = ["time.end=2e-8", "output.figures=false", "bodies.0.geometry.count=[3, 9]"]


@pytest.fixture(scope="module")
def sim():
    sim = Simulation(load_case("taylor", SHORT))
    sim.run(1e-8)
    return sim


def test_run_takes_a_finite_time_not_before_now(sim):
    step = sim.state.step
    for bad in (float("inf"), float("nan"), "2e-8", [2e-8], True):
        with pytest.raises(ValueError, match=r"run\(t_end = .*\): a finite time in seconds"):
            sim.run(bad)
    with pytest.raises(ValueError, match=r"run\(t_end = 5e-09\): before the simulation's "
                                         r"time, t = 1e-08 s; it runs forward only"):
        sim.run(5e-9)
    sim.run(1e-8)  # now itself: nothing to do, no error
    assert sim.state.step == step  # nothing stepped
    sim.run(np.float32(1.2e-8))  # a numpy number is a number
    sim.run(np.float64(1.5e-8))
    assert sim.state.time == 1.5e-8 and sim.state.step > step


def test_a_callback_that_is_not_a_function_is_refused_before_a_step(sim, tmp_path):
    step = sim.state.step
    with pytest.raises(TypeError, match=r"run\(callback = 5\): a function of the simulation"):
        sim.run(callback=5)
    assert sim.state.step == step
    with pytest.raises(TypeError, match=r"run_case\(callback = 5\)"):
        run_case(load_case("taylor", SHORT), tmp_path / "c", callback=5)
    assert not (tmp_path / "c").exists()  # (no summary left 'running')
    with pytest.raises(ValueError, match=r"run_case\(if_exists = 'replace'\): 'keep', "
                                         r"'refuse' or 'overwrite'"):
        run_case(load_case("taylor", SHORT), tmp_path / "r", if_exists="replace")


def test_a_case_that_is_not_validated_is_refused():
    case = load_case("taylor", SHORT)
    for call in (lambda: Simulation(case.model_dump()), lambda: Simulation("taylor"),
                 lambda: run_case({"name": "x"}, "nowhere")):
        with pytest.raises(TypeError, match=r"case is a (dict|str); it needs a validated "
                                            r"case: impactsph.load_case"):
            call()
    with pytest.raises(CaseError, match=r"load_case\(overrides = 'time.end=3e-6'\): a list "
                                        r"of KEY=VALUE strings"):
        load_case("taylor", "time.end=3e-6")
    with pytest.raises(CaseError, match=r"load_case\(123\): a case file's path"):
        load_case(123)


def test_a_case_changed_after_its_validation_is_checked_again(tmp_path):
    """pydantic checks a case's fields when it is made, not when one is assigned: a changed
    case is validated again by ``Simulation`` and ``run_case``, before any work."""
    case = load_case("taylor", SHORT)
    case.time.end = -1.0
    with pytest.raises(CaseError, match=r"^Simulation\(case\): the case was changed after its "
                                        r"validation and is no longer valid: time.end = -1.0: "
                                        r"Input should be greater than 0$"):
        Simulation(case)
    case = load_case("taylor", SHORT)
    case.viscosity.alpha1 = "a lot"
    with pytest.raises(CaseError, match=r"^run_case\(case\): .* viscosity.alpha1 = 'a lot'"):
        run_case(case, tmp_path / "v")
    assert not (tmp_path / "v").exists()
    case = load_case("taylor", SHORT)
    case.time.end = 1e-8  # a valid change is taken
    assert Simulation(case).case.time.end == 1e-8


def test_a_state_array_of_another_shape_is_refused_naming_it(sim):
    state = sim.state
    n = state.n
    for name, bad, shown in (("velocity", np.zeros((n, 3)), f"shape ({n}, 3)"),
                             ("velocity", [[0.0, 0.0]], "a list"),
                             ("deviatoric_stress", np.zeros((n, 2, 2)), f"shape ({n}, 2, 2)"),
                             ("density", np.zeros(n - 1), f"shape ({n - 1},)")):
        kept = getattr(state, name)
        setattr(state, name, bad)
        try:
            with pytest.raises(ValueError) as info:
                sim.run()
        finally:
            setattr(state, name, kept)
        message = str(info.value)
        assert message.startswith(f"state.{name}: this state's {n} particles in 2D need an "
                                  f"array of shape "), message
        assert message.endswith(f"; got {shown}"), message
    kept = state.position
    state.position = kept.ravel()
    try:
        with pytest.raises(ValueError, match=r"state.position: an array of shape \(n, dim\)"):
            sim.run()
    finally:
        state.position = kept

    def shrink(s):  # a callback that replaces an array: refused before any pass reads it
        s.state.velocity = np.zeros((3, 2))
    with pytest.raises(ValueError, match=r"state.velocity: .* got shape \(3, 2\)"):
        sim.run(callback=shrink)


def test_a_kernel_function_numba_has_not_compiled_is_refused_at_registration():
    """A plain Python pressure would stop every later run's compilation, whatever its
    models: it is refused when registered, and nothing is registered."""
    with pytest.raises(TypeError, match=r"equation of state 'broken': pressure = .* is not "
                                        r"compiled by numba"):
        EOS.register(EquationOfState(name="broken", pressure=lambda *a: 0.0,
                                     source="a test"))
    assert "broken" not in EOS
    compiled = nb.njit(lambda *a: 0.0)
    assert hasattr(compiled, "py_func")  # (what a numba dispatcher has, and is asked for)


def test_a_plugin_given_by_override_is_held_by_its_absolute_path(tmp_path, monkeypatch):
    """A plugin file named relative to the current directory is held by its absolute path,
    as a case file's are, so that a restart elsewhere finds it."""
    (tmp_path / "noop_plugin.py").write_text("X = 1\n")
    monkeypatch.chdir(tmp_path)
    case = load_case("taylor", [*SHORT, 'plugins=["noop_plugin.py"]'])
    assert case.plugins == [os.path.join(str(tmp_path), "noop_plugin.py")]
