"""Example 2: the Taylor bar on a rigid wall.

Measures at the end of the run: the final length over the initial one, ``L_f / L_0``, with
the length taken as the span of the particles along the bar plus one spacing (so that it is
``L_0`` at t = 0); the half-width of the footprint on the wall over ``B/2`` (the particles
within one spacing of the wall, plus half a spacing); plastic work and kinetic energy kept.
One-dimensional theories (Taylor; Wilkins & Guinan) put ``L_f / L_0`` at about 0.75-0.87 for
this bar (NOTES 10).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The band of one-dimensional theory for L_f / L_0 (NOTES 10).
LENGTH_RATIO_BAND = (0.75, 0.87)


def bar_measures(x0: np.ndarray, x: np.ndarray, axis: int, spacing: list[float],
                 wall_level: float) -> dict[str, float]:
    """Length ratio and footprint half-width ratio of a bar along ``axis`` standing on a wall
    at ``wall_level`` (initial positions ``x0``, current ``x``)."""
    along = spacing[axis]
    L0 = x0[:, axis].max() - x0[:, axis].min() + along
    Lf = x[:, axis].max() - x[:, axis].min() + along
    lateral = [a for a in range(x.shape[1]) if a != axis]
    centre = x0[:, lateral].mean(axis=0)
    half0 = np.max(np.linalg.norm(x0[:, lateral] - centre, axis=1)) + 0.5 * spacing[lateral[0]]
    foot = x[:, axis] < wall_level + along
    half = np.max(np.linalg.norm(x[foot][:, lateral] - centre, axis=1)) + 0.5 * spacing[
        lateral[0]]
    return {"final_length_ratio": float(Lf / L0), "footprint_half_width_ratio": float(half / half0),
            "final_length": float(Lf), "initial_length": float(L0)}


def taylor_metrics(sim: Any) -> dict[str, Any]:
    """Example 2's measures (see the module docstring)."""
    body = sim.case.bodies[0]
    axis = sim.case.dimension - 1  # the bar stands along the last axis
    wall = sim.case.boundaries[0].point[axis] if sim.case.boundaries else 0.0
    out = bar_measures(sim.state.initial_position, sim.state.position, axis,
                       body.geometry.spacings(), wall)
    lo, hi = LENGTH_RATIO_BAND
    out["length_ratio_in_1d_band"] = bool(lo <= out["final_length_ratio"] <= hi)
    out["mass_total"] = float(sim.state.mass.sum())
    return out
