"""The packed records (:mod:`impactsph.physics.records`): the viscous acceleration's columns are
last, and the CPU's rows carry them only where a correction or a switch reads them; records
without them give the same rates, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from impactsph import Simulation, load_case
from impactsph.physics.records import record_columns


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("options", [{}, {"correction_matrix": True, "artificial_stress": True,
                                          "viscosity_factor": True, "velocity_gradient": True,
                                          "work_velocity": True}])
def test_the_viscous_acceleration_is_last(dim, options):
    cols = record_columns(dim, **options)
    assert cols["columns"] == cols["u"] + dim
    starts = sorted(v for k, v in cols.items() if k not in ("columns", "width"))
    assert starts[-1] == cols["u"]
    assert cols["width"] % 8 == 0 and cols["columns"] <= cols["width"] < cols["columns"] + 8


def small_taylor(dim: int, *overrides: str) -> Simulation:
    """The paper's Taylor bar on its wall, small: 8 x 12 particles in 2D, a 6 x 6 x 8 block in
    3D; ``overrides`` last."""
    extra = (["dimension=3", "bodies.0.geometry.count=[6, 6, 8]",
              "bodies.0.geometry.size=[0.0045, 0.0045, 0.006]",
              "bodies.0.geometry.origin=[-0.00225, -0.00225, 0.0]",
              "bodies.0.velocity=[0.0, 0.0, -200.0]", "boundaries.0.point=[0.0, 0.0, 0.0]",
              "boundaries.0.normal=[0.0, 0.0, 1.0]",
              "analysis=none"] if dim == 3 else ["bodies.0.geometry.count=[8, 12]"])
    return Simulation(load_case("taylor", [*extra, "output.figures=false", *overrides]))


def _taylor(scheme: str, dim: int) -> Simulation:
    return small_taylor(dim, f'viscosity.scheme="{scheme}"', "time.max_steps=30")


@pytest.mark.parametrize("dim", [2, 3])
def test_records_without_the_viscous_acceleration_give_the_same_rates(dim):
    """AV on the Taylor bar on a wall (ghosts), after 30 steps: the rates from the lean rows
    equal those from rows with the viscous acceleration's columns, to the bit; AC's rows keep
    them."""
    sim = _taylor("av", dim)
    sim.run()
    backend = sim.solver.backend
    k = backend.passes
    assert backend._packed.shape[1] == k.U == k.RECORD_COLUMNS - dim
    lean = [np.copy(r) for r in sim.solver.rates(sim.state)[:4]]
    backend.record_columns = lambda viscosity: k.RECORD_COLUMNS
    full = [np.copy(r) for r in sim.solver.rates(sim.state)[:4]]
    assert backend._packed.shape[1] == k.RECORD_COLUMNS
    assert np.abs(full[0]).max() > 0.0
    for a, b in zip(lean, full, strict=True):
        np.testing.assert_array_equal(a, b)
    ac = _taylor("ac", dim)
    ac.solver.rates(ac.state)
    assert ac.solver.backend._packed.shape[1] == ac.solver.backend.passes.RECORD_COLUMNS
