"""The neighbour loops of a run whose smoothing lengths are all the same
(:meth:`impactsph.physics.rates.CpuRates.neighbour_loops`, ``PassOptions.uniform_h``): they take
the particle's h for each pair's, which it then is to the bit, so the rates are those of the
run's own loops to the bit; a run whose h differ, or may come to differ (the stretch), keeps
its own loops."""

from __future__ import annotations

import numpy as np
import pytest
from test_records import small_taylor

from impactsph import Simulation

#: a small Taylor bar on its wall (ghosts), every neighbour loop on: the kernel gradient
#: correction of the forces (moment pass), the hourglass control
STABILISED = ['stabilisation.gradient_correction="velocity_gradient_and_forces"',
              "stabilisation.hourglass=0.05"]


def _taylor(dim: int, *overrides: str) -> Simulation:
    return small_taylor(dim, "time.max_steps=20", *overrides)


def _rates(sim: Simulation) -> list[np.ndarray]:
    return [np.copy(r) for r in sim.solver.rates(sim.state)]


def _with_loops(sim: Simulation, module) -> list[np.ndarray]:
    """The solver's rates with every evaluation's neighbour loops from ``module``."""
    backend = sim.solver.backend
    chosen = backend.neighbour_loops
    backend.neighbour_loops = lambda uniform_h: module
    try:
        return _rates(sim)
    finally:
        backend.neighbour_loops = chosen


def _same_bits(a: list[np.ndarray], b: list[np.ndarray]) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.shape == y.shape and x.tobytes() == y.tobytes()


@pytest.mark.parametrize("dim", [2, 3])
def test_one_h_takes_the_uniform_loops_with_the_same_bits(dim):
    """After 20 steps on the wall, the uniform loops ran the run, and their rates equal the
    run's own loops' to the bit.  2D: AC (its viscous acceleration written by the pair pass
    for the correction) with the moment and hourglass passes; 3D: the paper's AV without
    them (the set other tests compile; the 3D loops' own part is the skin's gathering, which
    both run)."""
    sim = _taylor(dim, *STABILISED) if dim == 2 else _taylor(dim, 'viscosity.scheme="av"')
    sim.run()
    backend = sim.solver.backend
    assert backend._uniform is not None and backend._loops is backend._uniform
    assert backend.passes.UNIFORM_H is False and backend._uniform.UNIFORM_H is True
    uniform = _rates(sim)
    own = _with_loops(sim, backend.passes)
    assert np.abs(own[0]).max() > 0.0 and np.abs(own[3]).max() > 0.0
    _same_bits(uniform, own)


def test_a_particle_with_its_own_h_takes_the_runs_own_loops():
    """One particle's h set 10% larger after 20 steps: the next evaluation runs the run's own
    loops (which read each pair's h) and gives their rates; the uniform loops would have
    given others."""
    sim = _taylor(2, *STABILISED)
    sim.run()
    backend = sim.solver.backend
    assert backend._loops is backend._uniform
    sim.state.smoothing_length[40] *= 1.1
    sim.solver._build(sim.state)  # the ghosts' h from their sources' (as at a list build)
    chosen = _rates(sim)
    assert backend._loops is backend.passes
    _same_bits(chosen, _with_loops(sim, backend.passes))
    wrong = _with_loops(sim, backend._uniform)
    assert not np.array_equal(chosen[0], wrong[0])


def test_the_stretch_keeps_the_runs_own_loops_from_the_start():
    """With the stretch (``kernel.max_stretch`` > 1) every h starts equal and parts at a later
    build: the run compiles and runs its own loops only."""
    sim = _taylor(2, "kernel.max_stretch=1.5", "time.max_steps=3")
    sim.run()
    assert float(np.ptp(sim.state.smoothing_length)) == 0.0  # still equal: no list rebuilt
    backend = sim.solver.backend
    assert backend._uniform is None and backend._loops is backend.passes


def test_an_evaluation_without_the_answer_checks_the_h_itself():
    """``CpuRates.evaluate`` called without ``uniform_h`` (as by a script of one's own) looks
    at the rows' h: the uniform loops while they are the same, the run's own once one
    differs."""
    sim = _taylor(2, *STABILISED)
    sim.run()
    solver, backend = sim.solver, sim.solver.backend
    arrays = solver._arrays(sim.state)

    def evaluate():
        backend._loops = None
        backend.evaluate(solver.n_active, arrays, solver.table, solver.neighbours,
                         solver.viscosity, solver.buffers, solver.hourglass,
                         sim.state.hourglass_acceleration, n_bodies=solver.n_bodies)

    evaluate()
    assert backend._loops is backend._uniform
    arrays[6][3] *= 1.1  # the rows' h
    evaluate()
    assert backend._loops is backend.passes
