"""The total-Lagrangian solver: :class:`TotalLagrangianSolver`, the counterpart of
:class:`impactsph.solver.Solver` for ``formulation = "total_lagrangian"``
(:mod:`impactsph.physics.total_lagrangian`; docs/stabilisation.md, "Total-Lagrangian
formulation").

It returns the same ``(dv, drho, de, dS, dhg)`` as the updated-Lagrangian solver, so the
midpoint integrator and its compiled ``advance`` stage (the EOS, the strength model's return
map, the heating and the damage) are the same.  Rigid walls act through a penalty layer
(:func:`impactsph.boundaries.layer_push` with ``soft``, softer than
the updated-Lagrangian layer and with a continuous dashpot) and the integrator's
constraint; there are no wall ghosts.  One body per case (the case schema refuses more); it
does not fragment: its neighbours are those of t = 0 for the whole run.  CPU only.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .boundaries import Walls, layer_push
from .errors import CaseError
from .kernels import SUPPORT_RADIUS
from .materials import carried_pressure
from .models.columns import DAMAGE
from .neighbours import NeighbourList
from .physics import total_lagrangian as tl
from .physics.rates import RateBuffers, ViscositySettings, compiled_passes
from .state import ParticleState


class TotalLagrangianSolver:
    """Evaluates ``(dv/dt, drho/dt, de/dt, dS/dt, dhg/dt)`` (the last with no rows) for a
    state, on the reference configuration ``state.initial_position``.

    ``viscosity``: Monaghan's artificial viscosity (its ``pair`` parameters ``(alpha1, alpha2,
    epsilon, _)``); ``hourglass``: the coefficient alpha of the hourglass penalty
    (:func:`impactsph.physics.total_lagrangian.hourglass_pair`), 0 for none; ``wall_layer``:
    the walls' penalty layer in particle spacings (needed with walls)."""

    def __init__(self, state: ParticleState, table: np.ndarray, viscosity: ViscositySettings,
                 walls: Walls | None = None, hourglass: float = 0.0, wall_layer: float = 0.0):
        self.table = table
        self.viscosity = viscosity
        self.visc = np.array(viscosity.pair[:3], dtype=np.float64)
        self.hourglass = float(hourglass)
        self.walls = walls if walls is not None and len(walls) else None
        self.wall_layer = float(wall_layer)
        if self.walls is not None and self.wall_layer <= 0.0:
            raise ValueError("the total-Lagrangian solver holds walls by their penalty layer: "
                             "wall_layer must be positive")
        self.n_active = n = state.n
        self.dim = dim = state.dim
        self.backend = SimpleNamespace(device="cpu")
        self.pair_evaluations = 0
        self.rate_evaluations = 0
        self.powers = (0.0, 0.0, 0.0)
        self.wall_force = np.zeros(dim)
        self.buffers = RateBuffers(n, dim, contact=False, corrected=False, hourglass=False)
        self._pressure = np.empty(n)
        self._damage = np.empty(n)
        self.F = np.zeros((n, dim, dim))
        self.Fdot = np.zeros((n, dim, dim))
        self._Q = np.zeros((n, dim, dim))
        self._pressures = compiled_passes(dim).pressures
        X = np.ascontiguousarray(state.initial_position, dtype=np.float64)
        V0 = tl.reference_volumes(state.mass, state.material, table)
        self.ref = tl.reference(X, V0, state.smoothing_length, state.body)
        bad = np.flatnonzero(self.ref.det <= tl.SINGULAR_MOMENT ** dim)
        if bad.size:
            i = int(bad[0])
            raise CaseError(f"bodies: particle {i} at {X[i].tolist()} has too few reference "
                            f"neighbours for the total-Lagrangian gradient (det M = "
                            f"{self.ref.det[i]:.3g})")
        #: the reference neighbour list, as the checkpoints store a list (never rebuilt)
        self.neighbours = NeighbourList.build(X, SUPPORT_RADIUS * float(
            state.smoothing_length.max()), 0.0)
        self._ghost_src = np.zeros(0, dtype=np.int64)
        self._ghost_wall = np.zeros(0, dtype=np.int64)
        self._pairs = int(self.ref.neighbours.shape[0])
        #: m / (m + added mass), None without added mass (see :class:`~impactsph.solver.Solver`)
        self._inertia = state.inertia_fraction()

    def restore(self, state: ParticleState, neighbours: NeighbourList, ghost_src: np.ndarray,
                ghost_wall: np.ndarray) -> None:
        """Restart from a checkpoint: nothing to take over (the reference configuration is
        ``state.initial_position``, set up already)."""

    def rates(self, state: ParticleState, time: float | None = None):
        """Rates at ``state``: ``(dv, drho, de, dS, dhg)``, ``dhg`` with no rows."""
        b, ref, n = self.buffers, self.ref, self.n_active
        self._pressures(state.density, state.specific_energy, state.material, self.table,
                        self._pressure)
        np.copyto(self._damage, state.material_state[:, DAMAGE])
        tl.deformation_pass(n, state.position, state.velocity, ref.V0, state.mass,
                            state.density, self._pressure, state.deviatoric_stress,
                            self._damage, state.material, self.table, ref.offsets,
                            ref.neighbours, ref.grad, ref.K, self.F, self.Fdot, self._Q,
                            b.drho, b.dS, b.de)
        tl.force_pass(n, state.position, state.velocity, ref.X, ref.V0, state.mass,
                      state.smoothing_length, state.density, state.material, self.table,
                      ref.offsets, ref.neighbours, ref.grad, ref.w, ref.dw, self.F, self._Q,
                      self.visc, self.hourglass, b.dv, b.de, b.de_visc)
        self.powers = (float(state.mass @ b.de_visc), 0.0, 0.0)
        if self.walls is not None:
            w = self.walls
            self.wall_force = layer_push(n, state.position, state.velocity, state.mass,
                                         state.material, self.table, w.points, w.normals,
                                         self.wall_layer, b.dv, b.de, True)
        if self._inertia is not None:  # forces per own mass -> accelerations
            b.dv[:n] *= self._inertia[:, None]
        self.pair_evaluations += self._pairs
        self.rate_evaluations += 1
        return b.dv, b.drho, b.de, b.dS, b.dhg

    def pressure(self, state: ParticleState) -> np.ndarray:
        """Pressure (Pa) of each particle of ``state``, from the equations of state, a
        damaged particle's tension reduced by ``1 - D`` (as the forces see it)."""
        p = self._pressures(state.density, state.specific_energy, state.material, self.table,
                            np.empty(state.n))
        damage = state.material_state[:, DAMAGE]
        return carried_pressure(p, damage)
