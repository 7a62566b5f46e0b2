"""Prescribed motion: regions of a body whose particles move at a prescribed velocity
(``[[bodies.driven]]``: loading platens, the grips of a tension test), and their reaction.

A driven particle is integrated as a clamped one (its computed acceleration is not applied,
``ParticleState.clamped``), and after each integrator stage its velocity is set to the
prescribed ``v_p(t)`` at the stage's time, so that its position follows
``x(t + dt) = x(t) + dt v_p(t + dt/2)``, the midpoint rule's.  Each component of ``v_p`` is a
number or an expression of ``t`` (numexpr, as :mod:`impactsph.initial`).

The region's **reaction**, the force its support applies to the body, is what the prescribed
motion needs beyond the forces the body's particles exert on the region's::

    F_r = sum_i m_i (v_p(t + dt) - v_p(t)) / dt - sum_i m_i dv_i/dt          (N, or N/m in 2D)

with ``dv_i/dt`` the accelerations of the step's midpoint evaluation; ``history.csv`` records
it per region (``reaction_force_NAME_x``, ...).  Its work ``F_r . v_p(t + dt/2) dt``, summed,
is the ``external_work`` column, and the total energy error is measured on
``KE + IE - external_work``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numexpr
import numpy as np

from .geometry import inside
from .initial import CONSTANTS


def prescribed(components: list[Any], t: float) -> np.ndarray:
    """The prescribed velocity at time ``t`` (numbers and expressions of ``t``)."""
    return np.array([float(numexpr.evaluate(c, local_dict={**CONSTANTS, "t": np.float64(t)},
                                             global_dict={}))
                     if isinstance(c, str) else float(c) for c in components])


@dataclass
class DrivenRegion:
    """One driven region: its particles and its prescribed velocity."""

    name: str
    rows: np.ndarray  #: the particles (indices into the state)
    components: list[Any]  #: per axis a number or an expression of t
    mass: float  #: of its particles (kg, or kg/m in 2D)
    #: the last few ``t -> v_p(t)``: a step asks for t + dt/2 and t + dt twice each
    _recent: dict[float, np.ndarray] = field(default_factory=dict, repr=False)

    def velocity(self, t: float) -> np.ndarray:
        v = self._recent.get(t)
        if v is None:
            if len(self._recent) >= 4:
                self._recent.clear()
            v = self._recent[t] = prescribed(self.components, t)
        return v


@dataclass
class Drivers:
    """The driven regions of a run, their reactions and the work they did."""

    regions: list[DrivenRegion]
    reaction: dict[str, np.ndarray] = field(default_factory=dict)  #: last step's, per region
    impulse: np.ndarray | None = None  #: the supports' impulse beyond the clamp's (N s)
    work: float = 0.0  #: J (J/m in 2D): the supports' work on the body

    @classmethod
    def of(cls, case: Any, state: Any) -> Drivers | None:
        """The driven regions of ``case`` over the particles of ``state`` (None if none),
        chosen by their initial positions, body by body."""
        regions = []
        for b, body in enumerate(case.bodies):
            members = np.flatnonzero(state.body == b)
            for drive in body.driven:
                sel = inside(state.initial_position[members], drive.origin, drive.size)
                rows = members[sel]
                regions.append(DrivenRegion(drive.name, rows, list(drive.velocity),
                                            float(state.inertial_mass[rows].sum())))
        if not regions:
            return None
        return cls(regions, impulse=np.zeros(state.dim))

    def apply(self, velocity: np.ndarray, t: float) -> None:
        """Set the driven particles' velocity to the prescribed one at ``t``."""
        for r in self.regions:
            velocity[r.rows] = r.velocity(t)

    def account(self, mass: np.ndarray, dv: np.ndarray, t: float, dt: float,
                mean_velocity: bool = False) -> None:
        """The reactions of the step from ``t`` to ``t + dt`` (``dv``: the midpoint
        accelerations), their work, and the supports' impulse beyond the clamps' (which
        counts ``-dt sum m dv`` for every held particle, driven ones included).  The work is
        the reaction's at the prescribed velocity at ``t + dt/2``, or with ``mean_velocity``
        (the compatible energy update, which gives the forces their work at the step's mean
        velocity) at ``(v(t) + v(t + dt)) / 2``."""
        for r in self.regions:
            v0, v1 = r.velocity(t), r.velocity(t + dt)
            vm = 0.5 * (v0 + v1) if mean_velocity else r.velocity(t + 0.5 * dt)
            change = r.mass * (v1 - v0)
            force = change / dt - mass[r.rows] @ dv[r.rows]
            self.reaction[r.name] = force
            self.impulse += change
            self.work += float(force @ vm) * dt
