"""With walls (ghosts), the passes read extended arrays: the particles' rows, then the ghosts'.
The state's integrated fields are views of those rows (``Solver._allocate``), so nothing is
copied into them before each evaluation; a field handed an array of its own is copied as
before, and another state handed to the rates is bound in its turn, with the same results
to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph.loading import apply_overrides, read_case_dict, validate_case
from impactsph.models.columns import CARRIED
from impactsph.simulation import Simulation

FIELDS = ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
          "plastic_work", "material_state")


def taylor(*overrides: str) -> Simulation:
    data = read_case_dict("taylor")
    return Simulation(validate_case(apply_overrides(data, [
        "time.end=3e-6", "output.figures=false", "output.snapshot_times=[]", *overrides])))


@pytest.mark.parametrize("scheme", ["ac", "balsara"])
def test_the_state_is_the_extended_rows_across_rebuilds(scheme):
    """The fields are views of the extended arrays after the first build and after every
    rebuild (new ghosts, new arrays); with a viscosity switch the material state is not (its
    factor and memory take the carried array's columns after the common ones)."""
    sim = taylor(f'viscosity.scheme="{scheme}"')
    solver, state = sim.solver, sim.state
    aliased = dict((name, key) for key, name in solver._aliased())
    assert ("material_state" in aliased) == (scheme == "ac")
    builds = solver.neighbours.builds
    for _ in range(400):
        if solver.neighbours.builds >= builds + 2:
            break
        sim.run(sim.time + 1e-8)
    assert solver.neighbours.builds >= builds + 2
    for name, key in aliased.items():
        field = getattr(state, name)
        assert field.base is solver._ext[key], name
        assert field.shape[0] == state.n and field.flags.c_contiguous


def test_a_state_with_arrays_of_its_own_gives_the_same_run():
    """Hand the state new arrays (copies) halfway: the solver copies them into its rows again
    (the fallback), and the run ends bit for bit where the untouched one does."""
    plain, handed = taylor(), taylor()
    plain.run(1.5e-6)
    handed.run(1.5e-6)
    for name in FIELDS:
        setattr(handed.state, name, getattr(handed.state, name).copy())
    solver = handed.solver
    n = handed.state.n
    for key, _ in solver._aliased():  # the old rows, no longer the state's: spoiled
        solver._ext[key][:n] = np.nan
    builds = solver.neighbours.builds
    solver.rates(handed.state)  # the same positions: no rebuild, the copies copied in
    assert solver.neighbours.builds == builds
    for key, name in solver._aliased():
        field = getattr(handed.state, name)
        assert field.base is not solver._ext[key], name
        if key == "carried":  # the common columns: all the passes read without a switch
            rows, field = solver._ext[key][:n, :CARRIED], field[:, :CARRIED]
        else:
            rows = solver._ext[key][:n]
        np.testing.assert_array_equal(rows, field, err_msg=name)
    plain.run()
    handed.run()
    assert handed.state.step == plain.state.step
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(handed.state, name), getattr(plain.state, name),
                                      err_msg=name)


def test_rates_of_another_state_leave_the_run_alone():
    """The solver's arrays are the run's state's fields: rates asked for another state (a
    perturbed copy) bind that one instead and write nothing into the run's state, and the
    run then goes on to the same end as an untouched one."""
    plain, asked = taylor(), taylor()
    plain.run(1e-6)
    asked.run(1e-6)
    before = {name: getattr(asked.state, name).copy() for name in FIELDS}
    other = asked.state.copy()
    other.velocity *= 1.5
    other.density *= 1.001
    asked.solver.rates(other)
    assert asked.solver._bound is other
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(asked.state, name), before[name], err_msg=name)
    plain.run()
    asked.run()
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(asked.state, name), getattr(plain.state, name),
                                      err_msg=name)
