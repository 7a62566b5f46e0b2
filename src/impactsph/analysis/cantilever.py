"""Example 3: the Parkes cantilever.

Measures at the end of the run: the tip deflection, the mean displacement across the beam of
the particles carrying the tip mass (m), and its ratio to the length L; the plastic work; and
``max_neighbour_gap_over_h``, the largest distance between two particles that were neighbours
at t = 0 (within the kernel support 2h), over h.  It is about 2.6 in an intact beam and grows
where the particles separate: numerical fracture (the paper's Fig 16) shows as a large value.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..neighbours import NeighbourList


def initial_neighbour_pairs(x0: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Ordered pairs (i, j) closer than 2h at t = 0."""
    nl = NeighbourList.build(x0, 2.0 * h)
    i = np.repeat(np.arange(x0.shape[0]), np.diff(nl.offsets))
    return i, nl.indices


def max_neighbour_gap_over_h(x0: np.ndarray, x: np.ndarray, h: float) -> float:
    """Largest current distance between initial neighbours, over h."""
    i, j = initial_neighbour_pairs(x0, h)
    return float(np.max(np.linalg.norm(x[i] - x[j], axis=1)) / h)


def cantilever_metrics(sim: Any) -> dict[str, Any]:
    """Example 3's measures (see the module docstring)."""
    body = sim.case.bodies[0]
    s = sim.state
    out: dict[str, Any] = {}
    if body.tip_mass is not None:
        from ..geometry import inside

        region = body.tip_mass.region
        tip = inside(s.initial_position, region.origin, region.size)
        transverse = int(np.argmax(np.abs(body.tip_mass.velocity)))
        disp = s.position[tip, transverse] - s.initial_position[tip, transverse]
        length = float(s.initial_position[tip, 0].max() + 0.5 * body.geometry.spacings()[0])
        out["tip_deflection"] = float(abs(disp.mean()))
        out["tip_deflection_ratio"] = out["tip_deflection"] / length
        out["tip_initial_speed"] = sim.problem.info.get("tip_initial_speed")
    out["max_neighbour_gap_over_h"] = max_neighbour_gap_over_h(
        s.initial_position, s.position, float(s.smoothing_length.max()))
    return out
