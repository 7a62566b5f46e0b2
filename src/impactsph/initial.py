"""Initial conditions given as expressions of position: a body's ``velocity`` components may
be numbers or expressions of ``x``, ``y``, ``z`` (m), evaluated by numexpr at every particle,
e.g. a rigid rotation at 1000 rad/s about the z axis::

    velocity = ["-1000 * y", "1000 * x", 0.0]

or a bending mode, ``["0", "0.5 * sin(pi * x / 0.2)"]``.  numexpr's functions (``sin``,
``cos``, ``exp``, ``sqrt``, ``where``, ...) and the constants ``pi`` and ``e`` may be used;
any other name is refused when the case is read, with one line naming the field.
"""

from __future__ import annotations

import math
from typing import Any

import numexpr
import numpy as np

AXES = ("x", "y", "z")
CONSTANTS = {"pi": math.pi, "e": math.e}


def evaluate(expression: str, position: np.ndarray) -> np.ndarray:
    """The value of ``expression`` at each row of ``position`` (n, dim): an array of n."""
    names = {AXES[a]: np.ascontiguousarray(position[:, a]) for a in range(position.shape[1])}
    value = numexpr.evaluate(expression, local_dict={**CONSTANTS, **names}, global_dict={})
    return np.broadcast_to(np.asarray(value, dtype=np.float64), (position.shape[0],)).copy()


def check_expression(expression: str, dim: int, names: tuple[str, ...] | None = None
                     ) -> str | None:
    """Why ``expression`` cannot be an initial field of a ``dim``-dimensional case (None if it
    can): names other than the coordinates (or ``names``) and the constants, or bad syntax."""
    allowed = AXES[:dim] if names is None else names
    try:
        used = set(numexpr.NumExpr(expression).input_names)
    except Exception as exc:  # noqa: BLE001 - numexpr raises several types; say what it said
        return f"not an expression of {', '.join(allowed)} ({type(exc).__name__}: {exc})"
    unknown = sorted(used - set(allowed) - set(CONSTANTS))
    if unknown:
        return f"uses {', '.join(unknown)}; it may use {', '.join(allowed)}, pi and e"
    return None


def body_velocity(velocity: list[Any], position: np.ndarray) -> np.ndarray:
    """The initial velocity (n, dim) of the particles at ``position`` from a body's
    ``velocity`` (numbers and expressions, one per axis)."""
    n, dim = position.shape
    out = np.empty((n, dim))
    for a, component in enumerate(velocity):
        out[:, a] = (evaluate(component, position) if isinstance(component, str)
                     else float(component))
    return out


def max_speed(body: Any, dim: int) -> float:
    """The largest initial speed of a body's particles (m/s): its velocity's norm, or, with
    expressions, their largest over the body's particles (placed as the run places them)."""
    if not any(isinstance(c, str) for c in body.velocity):
        return float(np.linalg.norm(np.asarray(body.velocity, dtype=np.float64)))
    from .geometry import body_particles

    x = body_particles(body.geometry, dim).position
    return float(np.linalg.norm(body_velocity(body.velocity, x), axis=1).max())
