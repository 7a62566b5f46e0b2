"""The solver: neighbour list, rate passes and viscosity scheme composed into one ``rates``
function for the integrator."""

from __future__ import annotations

import numpy as np

from .config import Viscosity
from .kernels import SUPPORT_RADIUS
from .neighbours import NeighbourList
from .physics.correction import ENERGY_CORRECTIONS, VARIANTS
from .physics.rates import RateBuffers, rate_kernels
from .state import ParticleState


class Solver:
    """Evaluates ``(dv/dt, drho/dt, de/dt, dS/dt)`` for a state.

    ``n_active`` particles are integrated; particles beyond (ghosts) only take part in sums.
    The neighbour list carries a skin of ``skin_fraction`` times the kernel support and is
    rebuilt when a particle has moved by half the skin.
    """

    def __init__(self, state: ParticleState, table: np.ndarray, viscosity: Viscosity,
                 n_active: int | None = None, skin_fraction: float = 0.1):
        self.table = table
        self.viscosity = viscosity
        self.n_active = state.n if n_active is None else n_active
        self.dim = state.dim
        self.buffers = RateBuffers(state.n, state.dim)
        self._passes = rate_kernels(state.dim)
        support = SUPPORT_RADIUS * float(state.smoothing_length.max())
        self.neighbours = NeighbourList.build(state.position, support, skin_fraction * support)
        self.pair_evaluations = 0
        self.rate_evaluations = 0
        self.dv = np.zeros((state.n, state.dim))
        self.de = np.zeros(state.n)
        self.powers = (0.0, 0.0, 0.0)
        self.corrected = viscosity.scheme == "ac"
        # AC evaluates the viscosity with (1, 1) (eq 31); AV with the case's parameters
        self.alpha = (1.0, 1.0) if self.corrected else (viscosity.alpha1, viscosity.alpha2)

    def rates(self, state: ParticleState):
        """Rates of the active particles at ``state`` (Table 1's subroutine RATES)."""
        b = self.buffers
        particle_pass, pair_pass, stress_pass, correction_pass = self._passes
        self.neighbours.update(state.position,
                               SUPPORT_RADIUS * float(state.smoothing_length.max()))
        particle_pass(state.density, state.specific_energy, state.deviatoric_stress,
                      state.material, self.table, b.pressure, b.sound_speed, b.A, b.pc)
        visc = self.viscosity
        pair_pass(self.n_active, state.position, state.velocity, state.mass, state.density,
                  state.smoothing_length, state.body, b.sound_speed, b.A, b.pc,
                  self.neighbours.offsets, self.neighbours.indices,
                  self.alpha[0], self.alpha[1], visc.epsilon,
                  b.drho, b.dv_stress, b.dv_visc, b.de_stress, b.de_visc, b.L,
                  b.contact_force, b.pair_count)
        stress_pass(self.n_active, state.deviatoric_stress, b.L, state.material, self.table,
                    b.dS)
        np.add(b.dv_stress, b.dv_visc, out=self.dv)
        np.add(b.de_stress, b.de_visc, out=self.de)
        if self.corrected:
            correction_pass(self.n_active, state.position, state.velocity, state.mass,
                            state.density, state.smoothing_length, state.body,
                            self.neighbours.offsets, self.neighbours.indices, b.dv_visc,
                            visc.correction_h_ratio, VARIANTS[visc.correction],
                            ENERGY_CORRECTIONS[visc.energy_correction], b.dv_corr, b.de_corr)
            self.dv += b.dv_corr
            self.de += b.de_corr
        self.powers = self._energy_powers(state)
        self.pair_evaluations += int(b.pair_count[: self.n_active].sum())
        self.rate_evaluations += 1
        return self.dv, b.drho, self.de, b.dS

    def _energy_powers(self, state: ParticleState) -> tuple[float, float, float]:
        """Powers at the evaluated state (W): ``sum m (de/dt)_visc``, the artificial
        viscosity's heating; ``sum m v . (dv/dt)_corr``, the work rate of the AC correction
        force on the particles; ``sum m (de/dt)_corr``, the correction's heating.  Kept as
        ``self.powers``: after a step, those of its midpoint evaluation."""
        n, b = self.n_active, self.buffers
        m = state.mass[:n]
        heating = float(np.dot(m, b.de_visc[:n]))
        if not self.corrected:
            return heating, 0.0, 0.0
        work = float(np.dot(m, np.einsum("ia,ia->i", state.velocity[:n], b.dv_corr[:n])))
        return heating, work, float(np.dot(m, b.de_corr[:n]))
