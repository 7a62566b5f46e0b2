"""Example 2: the Taylor bar on a rigid wall.

Measures at the end of the run: the final length over the initial one, ``L_f / L_0``, with
the length taken as the span of the particles along the bar plus one spacing (so that it is
``L_0`` at t = 0); the half-width of the footprint on the wall over ``B/2`` (the particles
within one spacing of the wall, plus half a spacing); plastic work and kinetic energy kept.
One-dimensional theories (Taylor; Wilkins & Guinan) put ``L_f / L_0`` at about 0.75-0.87 for
this bar (NOTES 10).

In 3D (a cylinder, ``examples/taylor3d.toml``) the footprint is a radius, measured the same
way: the largest distance from the bar's axis among the particles within one spacing of the
wall, plus half a spacing, over the same measure of the whole bar at t = 0
(``footprint_radius_ratio``; 1 at t = 0, as the 2D ratio).  The axis is the line through the
initial centroid along the cylinder's ``axis``.  The footprint is also split into eight 45-degree
sectors about the axis, centred on the lateral coordinate axes and their diagonals;
``footprint_radius_ratio_min_sector`` is the smallest of their radii, so it equals
``footprint_radius_ratio`` for a round footprint and falls below it where the foot spreads
unevenly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..geometry import AXES

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


#: Sectors of the footprint in 3D: 8 of 45 degrees, centred on the axes and the diagonals.
N_SECTORS = 8


def cylinder_measures(x0: np.ndarray, x: np.ndarray, axis: int, spacing: list[float],
                      wall_level: float) -> dict[str, float]:
    """Length ratio and footprint radius ratio of a 3D bar (a cylinder) along ``axis``
    standing on a wall at ``wall_level`` (initial positions ``x0``, current ``x``): the 3D
    counterpart of :func:`bar_measures`, the half-width replaced by the distance from the
    axis (see the module docstring).  ``spacing``: per axis, as for :func:`bar_measures`."""
    along = spacing[axis]
    L0 = x0[:, axis].max() - x0[:, axis].min() + along
    Lf = x[:, axis].max() - x[:, axis].min() + along
    lateral = [a for a in range(3) if a != axis]
    across = spacing[lateral[0]]
    centre = x0[:, lateral].mean(axis=0)
    R0 = float(np.max(np.linalg.norm(x0[:, lateral] - centre, axis=1))) + 0.5 * across
    d = x[x[:, axis] < wall_level + along][:, lateral] - centre
    r = np.hypot(d[:, 0], d[:, 1])
    Rf = float(r.max()) + 0.5 * across
    sector = np.rint(np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi / N_SECTORS)).astype(int)
    sector %= N_SECTORS
    by_sector = np.zeros(N_SECTORS)
    np.maximum.at(by_sector, sector, r + 0.5 * across)
    return {"final_length_ratio": float(Lf / L0), "footprint_radius_ratio": Rf / R0,
            "footprint_radius_ratio_min_sector": float(by_sector.min()) / R0,
            "footprint_radius": Rf, "initial_radius": R0,
            "final_length": float(Lf), "initial_length": float(L0)}


def bar_axis(case: Any) -> int:
    """The axis the bar stands along: a cylinder's own axis, else the last one."""
    geometry = case.bodies[0].geometry
    return AXES.index(geometry.axis) if geometry.type == "cylinder" else case.dimension - 1


def bar_wall(case: Any, axis: int) -> float:
    """Where the (first) wall, the bar's, cuts ``axis``; 0 without walls."""
    return case.boundaries[0].point[axis] if case.boundaries else 0.0


def taylor_metrics(sim: Any) -> dict[str, Any]:
    """Example 2's measures (see the module docstring)."""
    body = sim.case.bodies[0]
    axis = bar_axis(sim.case)
    wall = bar_wall(sim.case, axis)
    measures = cylinder_measures if sim.case.dimension == 3 else bar_measures
    out = measures(sim.state.initial_position, sim.state.position, axis,
                   body.geometry.spacings(), wall)
    lo, hi = LENGTH_RATIO_BAND
    out["length_ratio_in_1d_band"] = bool(lo <= out["final_length_ratio"] <= hi)
    out["mass_total"] = float(sim.state.mass.sum())
    return out
