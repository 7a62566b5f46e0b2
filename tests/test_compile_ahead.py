"""Compiling ahead (:func:`impactsph.simulation.compile_kernels`): a sweep fills numba's disk
cache in one process before its workers start, with a small copy of each case whose compiled
code differs (:func:`impactsph.simulation.compile_key`), so that the workers compile
nothing."""

from __future__ import annotations

import json
import logging
import subprocess
import sys

import pytest

from impactsph import load_case
from impactsph import simulation as simulation_module
from impactsph.simulation import compile_case, compile_key

#: a fresh process compiles ahead for a case, then runs the case and lists every compiled
#: function that gained an entry (compiled, or loaded from the disk cache) during the run
_CHILD = """
import json, sys
from numba.core import dispatcher
from impactsph import Simulation, load_case
from impactsph.simulation import compile_kernels
case = load_case(sys.argv[1], json.loads(sys.argv[2]))
compile_kernels(case.dimension, case)
added = []
original = dispatcher.Dispatcher.add_overload
def add_overload(self, cres):
    added.append(self.py_func.__module__ + "." + self.py_func.__qualname__)
    return original(self, cres)
dispatcher.Dispatcher.add_overload = add_overload
sim = Simulation(case)
sim.run()
sim.summary()
print(json.dumps(sorted(set(added))))
"""


@pytest.mark.parametrize("name, overrides", [
    # an elastic-plastic bar with the Mie-Gruneisen EOS and AC on a wall, 2,400 particles
    # (more than the rate totals' serial limit): before 2026-12-07 the copy was an elastic
    # block of 16 particles with AC, and the run then compiled its stage (the materials'
    # return map and EOS), the models' functions, the parallel totals and the chunked
    # passes' driver for its own arguments
    ("taylor", ["bodies.0.geometry.count=[30, 80]"]),
    # two bodies, a viscosity switch, 202 particles
    ("bars", ['viscosity.scheme="balsara"']),
])
def test_a_run_after_compiling_ahead_for_it_compiles_nothing(name, overrides):
    result = subprocess.run(
        [sys.executable, "-c", _CHILD, name, json.dumps([*overrides, "time.max_steps=2"])],
        capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == []


def test_the_compile_key_ignores_what_the_code_only_reads():
    """One compile ahead serves runs that differ in numbers the compiled code reads (a
    speed, a viscosity coefficient, a yield stress); a scheme, a material model or a size
    across a pass's threshold makes another."""
    base = compile_key(load_case("taylor"))
    assert compile_key(load_case("taylor", ["viscosity.alpha1=0.7",
                                            "bodies.0.velocity=[0.0, -150.0]",
                                            "materials.iron.yield_stress=5e8"])) == base
    for other in (['viscosity.scheme="balsara"'], ['materials.iron.model="elastic"'],
                  ["bodies.0.geometry.count=[60, 200]"]):
        assert compile_key(load_case("taylor", other)) != base, other


def test_the_copy_keeps_the_cases_settings_and_its_bodies_materials():
    case = load_case("bars")
    copy = compile_case(1, case)
    assert copy["viscosity"] == case.viscosity.model_dump(mode="json")
    assert [b["material"] for b in copy["bodies"]] == [b.material for b in case.bodies]
    assert copy["materials"] == case.model_dump(mode="json")["materials"]
    assert copy["time"]["max_steps"] == 1 and not copy["output"]["figures"]


def test_a_copy_that_does_not_run_falls_back_to_the_elastic_block(monkeypatch, caplog):
    """Compiling ahead is an optimisation: a copy that fails is logged, and the elastic
    block runs instead."""
    ran = []

    def step(case):
        ran.append(case.name)
        if len(ran) == 1:
            raise ValueError("a setting the copy cannot take")

    monkeypatch.setattr(simulation_module, "_compile_step", step)
    with caplog.at_level(logging.WARNING, logger="impactsph.simulation"):
        simulation_module.compile_kernels(1, load_case("bars"))
    assert ran == ["compile_1d_like_bars", "compile_1d"]
    assert "a setting the copy cannot take" in caplog.text


def test_a_sweep_compiles_ahead_once_a_key_and_survives_a_key_that_fails(monkeypatch, caplog):
    """:func:`impactsph.sweep.compile_ahead` compiles once for cases of one key, once more for
    another, and a case whose key cannot be made on its own, with a warning."""
    from impactsph import sweep

    compiled = []
    monkeypatch.setattr(simulation_module, "compile_kernels",
                        lambda dim, case: compiled.append(case.name))
    same = [load_case("bars", [f"viscosity.alpha1={a}"]) for a in (0.3, 0.5)]
    other = load_case("bars", ['viscosity.scheme="balsara"'])
    broken = load_case("bars", ['name="broken"'])
    real = simulation_module.compile_key

    def key(case):
        if case.name == "broken":
            raise ValueError("no key")
        return real(case)

    monkeypatch.setattr(simulation_module, "compile_key", key)
    with caplog.at_level(logging.WARNING, logger="impactsph.sweep"):
        assert sweep.compile_ahead([*same, other, broken]) == 3
    assert compiled == ["bars", "bars", "broken"]
    assert "no key" in caplog.text
