"""The rates do not depend on the neighbour list's Verlet skin.

The skin only adds list entries beyond the kernel support, whose terms are zero: the
vectorised loops mask them (1D, 2D) or leave them out before the loop (3D, ``SKIN_FILTER``
in :mod:`impactsph.physics.passes`, ``support_range``).  So one rate evaluation of the same
state with no skin and with a wide one must agree to round-off (the sums' partial sums are
grouped differently), in every pass that loops over the neighbours: the pair pass, and with
an elastic case's defaults the moment pass (the corrected forces) and the hourglass pass.
A skin pair that was neither masked nor left out would show here as an error of the size of
one pair's term, many orders above round-off.  (A pair within the support that the loops
dropped would be dropped with either skin: that is ``tests/test_rates_reference.py``'s to
find, against sums over every pair; it fails, for one, when the 3D gathering keeps only
``q^2 < 3.9``.)
"""

from __future__ import annotations

import numpy as np
import pytest
from fields import random_deviator

from impactsph.loading import validate_case
from impactsph.simulation import Simulation

DX = 1e-3


def jittered_block(dim: int, skin: float, scheme: str) -> Simulation:
    """An elastic steel block with the elastic defaults (corrected forces, hourglass
    control), perturbed positions, velocities, stresses and smoothing lengths (the same
    perturbation whatever the skin)."""
    side = {2: 9, 3: 6}[dim]
    case = validate_case({
        "name": f"skin{dim}", "dimension": dim,
        "materials": {"steel": {"model": "elastic", "density": 7850.0, "youngs_modulus": 2e11,
                                "poisson_ratio": 0.3}},
        "bodies": [{"name": "a", "material": "steel", "velocity": [0.0] * dim,
                    "geometry": {"origin": [0.0] * dim, "size": [side * DX] * dim,
                                 "spacing": DX}}],
        "kernel": {"h_over_dx": 1.3}, "viscosity": {"scheme": scheme},
        "time": {"end": 1e-6, "neighbour_skin": skin}, "output": {"figures": False},
    })
    sim = Simulation(case)
    s = sim.state
    rng = np.random.default_rng(dim)
    s.position += rng.normal(0.0, 0.08 * DX, s.position.shape)
    s.velocity += rng.normal(0.0, 20.0, s.velocity.shape)
    s.density *= 1.0 + rng.normal(0.0, 2e-3, s.n)
    s.deviatoric_stress[:] = random_deviator(rng, s.n, dim, 2e8)
    s.smoothing_length *= 1.0 + rng.uniform(-0.05, 0.05, s.n)
    s.hourglass_acceleration[:] = rng.normal(0.0, 1e3, s.hourglass_acceleration.shape)
    sim.solver.neighbours = None  # the list for the perturbed state, with this run's skin
    sim.solver._build(s)
    return sim


@pytest.mark.parametrize("dim", [2, 3])
def test_rates_do_not_depend_on_the_skin(dim):
    rates = {}
    entries = {}
    for skin in (0.0, 0.5):
        sim = jittered_block(dim, skin, "av")
        assert sim.solver.hourglass > 0.0
        assert sim.solver.backend.options.gradient_correction == "velocity_gradient_and_forces"
        rates[skin] = [np.array(r[: sim.state.n], copy=True)
                       for r in sim.solver.rates(sim.state)]
        entries[skin] = sim.solver.neighbours.n_pairs
    assert entries[0.5] > 1.5 * entries[0.0]  # the wide skin's list holds many more pairs
    names = ("dv", "drho", "de", "dS", "dhg")
    for name, plain, wide in zip(names, rates[0.0], rates[0.5], strict=True):
        scale = np.abs(plain).max()
        assert scale > 0.0, name
        assert np.abs(wide - plain).max() <= 1e-12 * scale, name
