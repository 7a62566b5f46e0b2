"""The rate equations: the one place where the pair loop applies the physical terms.

``compute_rates`` evaluates, for every active particle ``i``, the right-hand sides of the
continuity (eq 22), momentum (eq 27), energy (eq 28) and Jaumann stress-rate (eq 14)
equations from its neighbour list.  Three passes:

1. per particle: pressure from the EOS, wave speed, ``A = sigma/rho^2`` and the compressive
   pressure term shown to other bodies;
2. per pair (gather: each ``i`` sums over its ``j``, so threads never write the same memory and
   the result does not depend on the thread count): continuity, velocity gradient, stress and
   viscous accelerations, stress work and viscous heating, contact terms;
3. per particle: Jaumann stress rate from the velocity gradient;
4. with the acceleration correction only, per pair again: the smoothed viscous acceleration
   that AC subtracts (:mod:`.correction`).

The dimension is a compile-time constant: :func:`rate_kernels` compiles the same source once
per dimension, so the small loops over components unroll.
"""

from __future__ import annotations

import math
from functools import cache

import numba as nb
import numpy as np

from ..kernels import cubic_spline_dwdr_q
from ..materials import B0, BULK, C0, EOS, GAMMA, RHO0, SHEAR, WAVE_MODULUS
from .contact import contact_acceleration_pair, contact_work_pair, in_contact
from .continuity import continuity_pair, velocity_gradient_pair
from .correction import (
    ENERGY_PAPER,
    ENERGY_WORK,
    SHEPARD,
    corrected_viscous_acceleration,
    correction_weight,
)
from .energy import stress_work_pair, viscous_heating_pair
from .eos import MIE_GRUNEISEN, linear_pressure, mie_gruneisen_pressure
from .momentum import stress_acceleration_pair, viscous_acceleration_pair
from .stress_rate import jaumann_stress_rate
from .viscosity import monaghan_viscosity


@nb.njit(inline="always", cache=True)
def material_pressure(table, k: int, rho: float, e: float) -> float:
    """Pressure of material ``k`` (row of the material table) at ``rho``, ``e``."""
    if table[k, EOS] == MIE_GRUNEISEN:
        return mie_gruneisen_pressure(
            rho, e, table[k, RHO0], table[k, BULK], table[k, B0], table[k, C0], table[k, GAMMA]
        )
    return linear_pressure(rho, table[k, RHO0], table[k, BULK])


#: LLVM may fuse multiply-adds and use reciprocals (deterministic on one machine; no
#: reassociation, so sums keep their order).
FASTMATH = {"contract", "arcp", "nsz"}
#: Particles per parallel work item: scratch arrays are allocated once per chunk.
CHUNK = 512


@cache
def rate_kernels(dim: int):
    """Compile the rate passes for dimension ``dim``; returns ``(particle_pass, pair_pass,
    stress_pass, correction_pass)``."""

    @nb.njit(parallel=True, cache=True)
    def particle_pass(m, rho, e, S, material, table, pressure, sound_speed, A, pc, volume):
        """Pass 1: ``P``, ``c = sqrt(M/rho)``, ``A = (-P I + S)/rho^2``, ``P/rho^2``,
        ``V = m/rho``."""
        for i in nb.prange(rho.shape[0]):
            volume[i] = m[i] / rho[i]
            k = material[i]
            p = material_pressure(table, k, rho[i], e[i])
            pressure[i] = p
            sound_speed[i] = math.sqrt(table[k, WAVE_MODULUS] / rho[i])
            inv_rho2 = 1.0 / (rho[i] * rho[i])
            for a in range(dim):
                for b in range(dim):
                    A[i, a, b] = S[i, a, b] * inv_rho2
                A[i, a, a] -= p * inv_rho2
            pc[i] = p * inv_rho2

    @nb.njit(inline="always", cache=True, fastmath=FASTMATH)
    def particle_sums(
        i, x, v, m, rho, h, body, sound_speed, A, pc, volume, offsets, indices,
        alpha1, alpha2, epsilon,
        drho, dv_stress, dv_visc, de_stress, de_visc, L, contact_force, pair_count,
        gradw, v_ij, r_ij,
    ):
        """Sums over the neighbours of particle ``i`` (eqs 22, 27, 28); ``gradw``, ``v_ij``,
        ``r_ij`` are scratch vectors."""
        A_i = A[i]
        drho_i = 0.0
        de_s = 0.0
        de_v = 0.0
        for a in range(dim):
            dv_stress[i, a] = 0.0
            dv_visc[i, a] = 0.0
            contact_force[i, a] = 0.0
            for b in range(dim):
                L[i, a, b] = 0.0
        count = 0
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            r2 = 0.0
            for a in range(dim):
                r_ij[a] = x[i, a] - x[j, a]
                r2 += r_ij[a] * r_ij[a]
            h_ij = 0.5 * (h[i] + h[j])
            inv_h = 1.0 / h_ij
            q2 = r2 * inv_h * inv_h
            if q2 >= 4.0 or r2 == 0.0:
                continue
            count += 1
            r = math.sqrt(r2)
            f = cubic_spline_dwdr_q(r * inv_h, inv_h, dim) / r
            vg = 0.0
            vr = 0.0
            for a in range(dim):
                gradw[a] = f * r_ij[a]
                v_ij[a] = v[i, a] - v[j, a]
                vg += v_ij[a] * gradw[a]
                vr += v_ij[a] * r_ij[a]
            volume_j = volume[j]
            same_body = body[i] == body[j]
            if same_body:
                drho_i += continuity_pair(rho[i], volume_j, vg)
                A_j = A[j]
                for a in range(dim):
                    dv_stress[i, a] += stress_acceleration_pair(m[j], A_i, A_j, gradw, a, dim)
                    for b in range(dim):
                        L[i, a, b] += velocity_gradient_pair(volume_j, v_ij[a], gradw[b])
                de_s += stress_work_pair(m[j], A_i, v_ij, gradw, dim)
            else:  # another body or a wall ghost: compression-only contact
                s_ij = pc[i] + pc[j]
                if in_contact(s_ij, vg):
                    drho_i += continuity_pair(rho[i], volume_j, vg)
                    for a in range(dim):
                        fa = contact_acceleration_pair(m[j], s_ij, gradw[a])
                        dv_stress[i, a] += fa
                        contact_force[i, a] += m[i] * fa
                    de_s += contact_work_pair(m[j], pc[i], s_ij, vg)
            pi_ij = monaghan_viscosity(
                vr, r2, h_ij, 0.5 * (sound_speed[i] + sound_speed[j]),
                0.5 * (rho[i] + rho[j]), alpha1, alpha2, epsilon,
            )
            if pi_ij != 0.0:
                for a in range(dim):
                    fa = viscous_acceleration_pair(m[j], pi_ij, gradw[a])
                    dv_visc[i, a] += fa
                    if not same_body:
                        contact_force[i, a] += m[i] * fa
                de_v += viscous_heating_pair(m[j], pi_ij, vg)
        drho[i] = drho_i
        de_stress[i] = de_s
        de_visc[i] = de_v
        pair_count[i] = count

    @nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
    def pair_pass(
        n_active, x, v, m, rho, h, body, sound_speed, A, pc, volume, offsets, indices,
        alpha1, alpha2, epsilon,
        drho, dv_stress, dv_visc, de_stress, de_visc, L, contact_force, pair_count,
    ):
        """Pass 2: sums over neighbours for every active particle, in parallel chunks."""
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for chunk in nb.prange(n_chunks):
            gradw = np.empty(dim)  # scratch vectors, allocated once per chunk
            v_ij = np.empty(dim)
            r_ij = np.empty(dim)
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                particle_sums(
                    i, x, v, m, rho, h, body, sound_speed, A, pc, volume, offsets, indices,
                    alpha1, alpha2, epsilon,
                    drho, dv_stress, dv_visc, de_stress, de_visc, L, contact_force, pair_count,
                    gradw, v_ij, r_ij,
                )

    @nb.njit(parallel=True, cache=True)
    def stress_pass(n_active, S, L, material, table, dS):
        """Pass 3: Jaumann rate (eq 14) from the velocity gradient."""
        for i in nb.prange(n_active):
            jaumann_stress_rate(L[i], S[i], table[material[i], SHEAR], dS[i])

    @nb.njit(inline="always", cache=True)
    def particle_correction(i, x, v, m, rho, h, body, offsets, indices, u, h_ratio,
                            variant, energy_mode, dv_corr, de_corr, weighted_u):
        """``-u_corr_i`` and its energy term for particle ``i`` (``weighted_u``: scratch)."""
        for a in range(dim):
            weighted_u[a] = 0.0
        weight_sum = 0.0
        paper_energy = 0.0
        self_weight = correction_weight(m[i] / rho[i], 0.0, h_ratio * h[i], dim)
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            if body[j] != body[i]:
                continue
            h_c = h_ratio * 0.5 * (h[i] + h[j])
            r2 = 0.0
            for a in range(dim):
                d = x[i, a] - x[j, a]
                r2 += d * d
            if r2 >= 4.0 * h_c * h_c:
                continue
            w = correction_weight(m[j] / rho[j], math.sqrt(r2), h_c, dim)
            weight_sum += w
            for a in range(dim):
                weighted_u[a] += w * u[j, a]
                paper_energy += 0.5 * w * (v[i, a] - v[j, a]) * u[j, a]
        work = 0.0
        for a in range(dim):
            net = corrected_viscous_acceleration(u[i, a], self_weight, weight_sum,
                                                 weighted_u[a], variant)
            dv_corr[i, a] = net - u[i, a]
            work -= v[i, a] * dv_corr[i, a]
        if energy_mode == ENERGY_WORK:
            de_corr[i] = work
        elif energy_mode == ENERGY_PAPER:
            if variant == SHEPARD:
                paper_energy /= weight_sum + self_weight
            de_corr[i] = paper_energy
        else:
            de_corr[i] = 0.0

    @nb.njit(parallel=True, cache=True)
    def correction_pass(n_active, x, v, m, rho, h, body, offsets, indices, u, h_ratio,
                        variant, energy_mode, dv_corr, de_corr):
        """Pass 4 (AC only): ``-u_corr_i`` (eqs 33-36) and its energy term, from the viscous
        accelerations ``u`` of pass 2 (evaluated with (1, 1)); neighbours of the same body
        within ``2 h_c``, ``h_c = h_ratio h``."""
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for chunk in nb.prange(n_chunks):
            weighted_u = np.empty(dim)
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                particle_correction(i, x, v, m, rho, h, body, offsets, indices, u, h_ratio,
                                    variant, energy_mode, dv_corr, de_corr, weighted_u)

    return particle_pass, pair_pass, stress_pass, correction_pass


class CpuRates:
    """The rate passes on the CPU (numba, threads): fills a :class:`RateBuffers`.

    A backend has one method, :meth:`evaluate`; :class:`impactsph.gpu.GpuRates` is the
    other one, with the same signature and the same results."""

    device = "cpu"

    def __init__(self, dim: int):
        self.dim = dim
        self._passes = rate_kernels(dim)

    def evaluate(self, n_active: int, arrays: tuple, table: np.ndarray, neighbours,
                 alpha1: float, alpha2: float, epsilon: float, correction: tuple | None,
                 b: RateBuffers) -> None:
        """Rates of the first ``n_active`` rows of ``arrays = (x, v, rho, e, S, m, h,
        material, body)`` (all rows, ghosts included, take part in the sums) into ``b``:
        ``pressure, sound_speed, A, pc, volume`` (pass 1), ``drho, dv_stress, dv_visc,
        de_stress, de_visc, L, contact_force, pair_count`` (pass 2), ``dS`` (pass 3) and,
        when ``correction = (h_ratio, variant, energy_mode)`` is given, ``dv_corr, de_corr``
        (pass 4)."""
        x, v, rho, e, S, m, h, material, body = arrays
        particle_pass, pair_pass, stress_pass, correction_pass = self._passes
        nl = neighbours
        particle_pass(m, rho, e, S, material, table, b.pressure, b.sound_speed, b.A, b.pc,
                      b.volume)
        pair_pass(n_active, x, v, m, rho, h, body, b.sound_speed, b.A, b.pc, b.volume,
                  nl.offsets, nl.indices, alpha1, alpha2, epsilon,
                  b.drho, b.dv_stress, b.dv_visc, b.de_stress, b.de_visc, b.L,
                  b.contact_force, b.pair_count)
        stress_pass(n_active, S, b.L, material, table, b.dS)
        if correction is not None:
            h_ratio, variant, energy_mode = correction
            correction_pass(n_active, x, v, m, rho, h, body, nl.offsets, nl.indices,
                            b.dv_visc, h_ratio, variant, energy_mode, b.dv_corr, b.de_corr)


class RateBuffers:
    """Work and output arrays of one rate evaluation, allocated once per run."""

    def __init__(self, n: int, dim: int):
        self.pressure = np.zeros(n)
        self.sound_speed = np.zeros(n)
        self.A = np.zeros((n, dim, dim))
        self.pc = np.zeros(n)
        self.volume = np.zeros(n)
        self.drho = np.zeros(n)
        self.dv_stress = np.zeros((n, dim))
        self.dv_visc = np.zeros((n, dim))
        self.de_stress = np.zeros(n)
        self.de_visc = np.zeros(n)
        self.L = np.zeros((n, dim, dim))
        self.dS = np.zeros((n, 3, 3))
        self.contact_force = np.zeros((n, dim))
        self.pair_count = np.zeros(n, dtype=np.int64)
        self.dv_corr = np.zeros((n, dim))
        self.de_corr = np.zeros(n)
