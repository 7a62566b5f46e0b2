"""Issue 11: the paper's Taylor bar (plane strain) converges onto an independent solution as
the particles are refined, with the defaults of a case of one's own: AV (1, 1), the walls'
options (the normal-stress contact and the penalty layer) and h = 1.3 dx growing where the
bar has stretched to at most 1.6 dx (``kernel.max_stretch = "auto"``, 1.23 for a material
that yields; ``validation/resolution.py``'s scheme "defaults"; docs/stabilisation.md,
"Defaults, and why").  At the paper's resolution (x1) and twice it (x2), 3 s and 25 s on two
threads.

The reference is the explicit Lagrangian finite-element solution of the same bar
(``validation/taylor_fem.py``, Q4 elements with mean dilatation, the package's return map and
Mie-Gruneisen pressure, ``tests/test_taylor_fem.py``): its length and fixed-band footprint at
64 elements across the half-width, and its volume in slabs above the wall at 32 across
(``validation/taylor_fem.py 32``; 32 and 64 across agree to 0.04% in length).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from impactsph.config import AUTO_MAX_STRETCH
from impactsph.loading import load_case
from impactsph.problems import analyse
from impactsph.simulation import Simulation

sys.path.insert(0, str(Path(__file__).parent.parent / "validation"))
import taylor_slabs as slabs  # noqa: E402
from resolution import SCHEMES  # noqa: E402

#: the named scheme of validation/resolution.py that these runs are
SCHEME = SCHEMES["taylor"]["defaults"]
#: the finite elements' L_f / L0 and fixed-band footprint (64 across), and volume per unit
#: depth (m^2) in the slabs 0-1, 1-2, 2-4, 4-8 and 8-30 mm above the wall (32 across)
FE_LENGTH, FE_FOOTPRINT = 0.8100, 1.651
FE_SLABS = np.array([14.662, 18.395, 29.763, 34.707, 95.864]) * 1e-6
EDGES = np.array(slabs.EDGES_MM) * 1e-3
#: issue 11's bound: the footprint moved 16-20% from x1 to x2 before any remedy
BOUND = 0.16


def run(factor: int) -> tuple[dict, np.ndarray]:
    """The summary and the slab volumes of the bar at ``factor`` times the paper's particles
    per direction."""
    sim = Simulation(load_case("taylor", [*SCHEME, "output.figures=false",
                                          f"bodies.0.geometry.count=[{21 * factor}, "
                                          f"{67 * factor}]"]))
    h0 = sim.state.smoothing_length.copy()
    sim.run()
    s = sim.state
    volumes = slabs.particle_slab_volumes(s.position, s.mass / s.density, 1, EDGES)
    growth = s.smoothing_length / h0
    return {**sim.summary(), **analyse("taylor", sim), "h_growth": (growth.min(),
                                                                    growth.max())}, volumes


@pytest.fixture(scope="module")
def runs():
    return run(1), run(2)


def test_both_resolutions_run_clean(runs):
    """No particle reaches the wall and the energy is kept to 1e-3 at both (measured 4.0e-4
    and 2.0e-4); the kernel grew where the foot spread, by at most the limit."""
    for summary, _ in runs:
        assert summary["wall_constraint_events"] == 0
        assert summary["total_energy_relative_error"] <= 1e-3
        assert summary["momentum_drift"] <= 1e-12
        low, high = summary["h_growth"]
        assert low >= 1.0 and high == pytest.approx(AUTO_MAX_STRETCH)


def test_footprint_moves_less_than_the_bound_and_towards_the_reference(runs):
    """Fixed band 1.947 -> 1.894 (-2.7%), one spacing 1.947 -> 1.788 (-8.2%): both smaller
    than the 16% of issue 11's bound, and the fixed-band error falls (+17.9% -> +14.7%;
    +7.3% at x4, docs/stabilisation.md).  The old defaults (1.2 dx, fixed h) moved the
    fixed band +1.8%, away from the finite elements."""
    (s1, _), (s2, _) = runs
    for key in ("footprint_half_width_ratio_fixed", "footprint_half_width_ratio"):
        assert abs(s2[key] / s1[key] - 1.0) < BOUND, key
    fixed1, fixed2 = s1["footprint_half_width_ratio_fixed"], s2["footprint_half_width_ratio_fixed"]
    assert fixed2 < fixed1 and abs(fixed2 - FE_FOOTPRINT) < abs(fixed1 - FE_FOOTPRINT)


def test_length_and_shape_converge_onto_the_finite_elements(runs):
    """L_f / L0 0.8463 -> 0.8308 against 0.8100 (errors +4.5% -> +2.6%; +1.2% at x4); the
    largest slab error -20.3% (1-2 mm) -> -8.7% (-2.6% at x4); the volume itself is kept
    (the slabs' sum) to 0.2%."""
    (s1, v1), (s2, v2) = runs
    e1, e2 = (abs(s["final_length_ratio"] - FE_LENGTH) for s in (s1, s2))
    assert e2 < 0.75 * e1
    worst1, worst2 = (np.abs(v / FE_SLABS - 1.0).max() for v in (v1, v2))
    assert worst2 < 0.5 * worst1
    for v in (v1, v2):
        assert v.sum() == pytest.approx(FE_SLABS.sum(), rel=2e-3)
