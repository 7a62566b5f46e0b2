"""The rate equations: the one place where the pair loop applies the physical terms.

For every active particle ``i`` the passes evaluate the right-hand sides of the continuity
(eq 22), momentum (eq 27), energy (eq 28) and Jaumann stress-rate (eq 14) equations from its
neighbour list:

1. per particle: pressure from the EOS, wave speed, ``A = sigma/rho^2``, ``P/rho^2`` and
   ``V = m/rho``, written into one *packed record* per particle, in the neighbour list's cell
   (Morton) order, so that a particle's neighbours are close in memory and each is read as
   two or three cache lines instead of a dozen arrays;
2. per pair (gather: each ``i`` sums over its ``j``, so threads never write the same memory and
   the result does not depend on the thread count): continuity, velocity gradient, stress and
   viscous accelerations, stress work and viscous heating, contact terms; then, still per
   particle, the Jaumann stress rate;
3. with the acceleration correction only, per pair again: the smoothed viscous acceleration
   that AC subtracts (:mod:`.correction`).

The dimension is a compile-time constant: :func:`rate_kernels` compiles the same source once
per dimension, so the small loops over components unroll.  The kernels are closures over
integers only, so numba's on-disk cache serves them to later processes.
"""

from __future__ import annotations

import math
from functools import cache

import numba as nb
import numpy as np

from ..kernels import cubic_spline_gradient_factor
from ..materials import B0, BULK, C0, EOS, GAMMA, RHO0, SHEAR, WAVE_MODULUS
from .contact import contact_acceleration_pair, contact_work_pair, in_contact
from .continuity import continuity_pair, velocity_gradient_pair
from .correction import (
    corrected_viscous_acceleration,
    correction_energy_rate,
    correction_weight,
)
from .energy import viscous_heating_pair
from .eos import MIE_GRUNEISEN, linear_pressure, mie_gruneisen_pressure
from .momentum import viscous_acceleration_pair
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
def chunk_size(n: int) -> int:
    """Particles per parallel work item: about eight items per thread (so that the threads
    share the work evenly even for a thousand particles), 16 to 512.  Each particle's sums
    are the same whatever the chunking."""
    return int(min(512, max(16, n // (8 * nb.get_num_threads()))))


def packed_layout(dim: int) -> dict[str, int]:
    """Columns of the packed particle record read by the pair loop: position, velocity,
    ``h``, ``m``, ``V = m/rho``, ``rho``, ``c``, ``P/rho^2``, body, the symmetric
    ``A = sigma/rho^2`` (its upper triangle, row by row: :func:`symmetric_index`), and the
    viscous acceleration ``u`` that pass 2 writes for AC; ``"width"`` is the row length,
    padded to whole cache lines (2, 2 and 3 lines of 64 bytes in 1D, 2D, 3D)."""
    n_sym = dim * (dim + 1) // 2
    cols = {"x": 0, "v": dim, "h": 2 * dim, "m": 2 * dim + 1, "volume": 2 * dim + 2,
            "rho": 2 * dim + 3, "c": 2 * dim + 4, "pc": 2 * dim + 5, "body": 2 * dim + 6,
            "A": 2 * dim + 7, "u": 2 * dim + 7 + n_sym}
    cols["width"] = (cols["u"] + dim + 7) // 8 * 8
    return cols


def symmetric_index(a: int, b: int, dim: int) -> int:
    """Position of component ``(a, b)`` of a symmetric ``dim x dim`` tensor stored as its
    upper triangle, row by row."""
    a, b = min(a, b), max(a, b)
    return a * dim - a * (a - 1) // 2 + (b - a)


@cache
def rate_kernels(dim: int):
    """Compile the rate passes for dimension ``dim``; returns ``(particle_pass, pair_pass,
    correction_pass)``."""
    lay = packed_layout(dim)
    X, V, H, M, VOL, RHO, C, PC, BODY, A0, U = (lay[k] for k in (
        "x", "v", "h", "m", "volume", "rho", "c", "pc", "body", "A", "u"))
    # columns of A's components: SYM[a][b] (a tuple of tuples: a compile-time constant)
    SYM = tuple(tuple(A0 + symmetric_index(a, b, dim) for b in range(dim))
                for a in range(dim))
    A00 = SYM[0][0]
    A01, A11 = (SYM[0][1], SYM[1][1]) if dim > 1 else (0, 0)
    A02, A12, A22 = (SYM[0][2], SYM[1][2], SYM[2][2]) if dim > 2 else (0, 0, 0)

    @nb.njit(parallel=True, cache=True)
    def particle_pass(order, x, v, m, rho, e, S, h, body, material, table, packed):
        """Pass 1: ``P``, ``c = sqrt(M/rho)``, and the packed record (``V = m/rho``,
        ``P/rho^2``, ``A = (-P I + S)/rho^2``, ...) of every particle, ghosts included, at its
        sorted position ``p`` (``order[p]`` is the particle)."""
        for p in nb.prange(order.shape[0]):
            i = order[p]
            k = material[i]
            pr = material_pressure(table, k, rho[i], e[i])
            c = math.sqrt(table[k, WAVE_MODULUS] / rho[i])
            inv_rho2 = 1.0 / (rho[i] * rho[i])
            row = packed[p]
            for a in range(dim):
                row[X + a] = x[i, a]
                row[V + a] = v[i, a]
                for b in range(a, dim):
                    row[SYM[a][b]] = S[i, a, b] * inv_rho2
                row[SYM[a][a]] -= pr * inv_rho2
            row[H] = h[i]
            row[M] = m[i]
            row[VOL] = m[i] / rho[i]
            row[RHO] = rho[i]
            row[C] = c
            row[PC] = pr * inv_rho2
            row[BODY] = body[i]

    @nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
    def pair_pass(n_active, order, P, offsets, indices, alpha1, alpha2, epsilon, S,
                  material, table, drho, dv, de, de_visc, contact_force, pair_count, dS,
                  chunk_size):
        """Pass 2: for every active particle ``i = order[p]``, in parallel chunks of sorted
        positions ``p``, the sums over its neighbours (eqs 22, 27, 28) in scalar accumulators
        (the compiler keeps them in registers) and its stress rate (eq 14); its viscous
        acceleration is also stored in its packed record for AC.  Ghosts (``order[p] >=
        n_active``) only take part as neighbours.  ``contact_force`` is written only if it
        has a row per particle (runs with several bodies or walls).

        The stress terms are regrouped, exactly in arithmetic: ``sum_j m_j A_i . grad W_ij
        = A_i . (sum_j m_j grad W_ij)`` and ``sum_j m_j A_i : (v_ij (x) grad W_ij) =
        A_i : (sum_j m_j v_ij (x) grad W_ij)``, so ``A_i`` is applied once per particle.
        (One function, no helper: numba caches a closure only if it captures no compiled
        function.)"""
        n = order.shape[0]
        n_chunks = (n + chunk_size - 1) // chunk_size
        track_contact = contact_force.shape[0] > 0
        for chunk in nb.prange(n_chunks):
            L = np.empty((dim, dim))  # scratch: the velocity gradient of one particle
            for p in range(chunk * chunk_size, min((chunk + 1) * chunk_size, n)):
                i = order[p]
                if i >= n_active:
                    for a in range(dim):
                        P[p, U + a] = 0.0
                    continue
                shear = table[material[i], SHEAR]
                Pi_ = P[p]
                xi0 = Pi_[X]
                vi0 = Pi_[V]
                xi1 = Pi_[X + 1] if dim > 1 else 0.0
                vi1 = Pi_[V + 1] if dim > 1 else 0.0
                xi2 = Pi_[X + 2] if dim > 2 else 0.0
                vi2 = Pi_[V + 2] if dim > 2 else 0.0
                hi, ci, rhoi, pci, bi = Pi_[H], Pi_[C], Pi_[RHO], Pi_[PC], Pi_[BODY]
                inv_hi = 1.0 / hi
                # accumulators: continuity / rho_i; sum m_j grad W (same body);
                # sum m_j A_j . grad W; contact and viscous accelerations; L;
                # T = sum m_j v_ij (x) grad W; energies
                cont = 0.0
                G0 = G1 = G2 = 0.0
                a0 = a1 = a2 = 0.0
                k0 = k1 = k2 = 0.0
                w0 = w1 = w2 = 0.0
                f0 = f1 = f2 = 0.0  # viscous push across bodies (part of the contact force)
                L00 = L01 = L02 = L10 = L11 = L12 = L20 = L21 = L22 = 0.0
                T00 = T01 = T02 = T10 = T11 = T12 = T20 = T21 = T22 = 0.0
                de_contact = 0.0
                de_v = 0.0
                count = 0
                for k in range(offsets[p], offsets[p + 1]):
                    Pj = P[indices[k]]
                    d0 = xi0 - Pj[X]
                    r2 = d0 * d0
                    d1 = d2 = 0.0
                    if dim > 1:
                        d1 = xi1 - Pj[X + 1]
                        r2 += d1 * d1
                    if dim > 2:
                        d2 = xi2 - Pj[X + 2]
                        r2 += d2 * d2
                    h_j = Pj[H]
                    if h_j == hi:  # equal smoothing lengths (the common case): no division
                        h_ij = hi
                        inv_h = inv_hi
                    else:
                        h_ij = 0.5 * (hi + h_j)
                        inv_h = 1.0 / h_ij
                    q2 = r2 * inv_h * inv_h
                    if q2 >= 4.0 or r2 == 0.0:
                        continue
                    count += 1
                    fq = cubic_spline_gradient_factor(math.sqrt(q2), inv_h, dim)
                    g0 = fq * d0
                    g1 = fq * d1
                    g2 = fq * d2
                    u0 = vi0 - Pj[V]
                    u1 = vi1 - Pj[V + 1] if dim > 1 else 0.0
                    u2 = vi2 - Pj[V + 2] if dim > 2 else 0.0
                    vg = u0 * g0 + u1 * g1 + u2 * g2
                    vr = u0 * d0 + u1 * d1 + u2 * d2
                    m_j = Pj[M]
                    volume_j = Pj[VOL]
                    same_body = Pj[BODY] == bi
                    if same_body:
                        cont += continuity_pair(1.0, volume_j, vg)
                        G0 += m_j * g0
                        a0 += m_j * Pj[A00] * g0
                        L00 += velocity_gradient_pair(volume_j, u0, g0)
                        T00 += m_j * u0 * g0
                        if dim > 1:
                            G1 += m_j * g1
                            a0 += m_j * Pj[A01] * g1
                            a1 += m_j * (Pj[A01] * g0 + Pj[A11] * g1)
                            L01 += velocity_gradient_pair(volume_j, u0, g1)
                            L10 += velocity_gradient_pair(volume_j, u1, g0)
                            L11 += velocity_gradient_pair(volume_j, u1, g1)
                            T01 += m_j * u0 * g1
                            T10 += m_j * u1 * g0
                            T11 += m_j * u1 * g1
                        if dim > 2:
                            G2 += m_j * g2
                            a0 += m_j * Pj[A02] * g2
                            a1 += m_j * Pj[A12] * g2
                            a2 += m_j * (Pj[A02] * g0 + Pj[A12] * g1 + Pj[A22] * g2)
                            L02 += velocity_gradient_pair(volume_j, u0, g2)
                            L12 += velocity_gradient_pair(volume_j, u1, g2)
                            L20 += velocity_gradient_pair(volume_j, u2, g0)
                            L21 += velocity_gradient_pair(volume_j, u2, g1)
                            L22 += velocity_gradient_pair(volume_j, u2, g2)
                            T02 += m_j * u0 * g2
                            T12 += m_j * u1 * g2
                            T20 += m_j * u2 * g0
                            T21 += m_j * u2 * g1
                            T22 += m_j * u2 * g2
                    else:  # another body or a wall ghost: compression-only contact
                        s_ij = pci + Pj[PC]
                        if in_contact(s_ij, vg):
                            cont += continuity_pair(1.0, volume_j, vg)
                            push = contact_acceleration_pair(m_j, s_ij, 1.0)
                            k0 += push * g0
                            k1 += push * g1
                            k2 += push * g2
                            de_contact += contact_work_pair(m_j, pci, s_ij, vg)
                    pi_ij = monaghan_viscosity(vr, r2, h_ij, 0.5 * (ci + Pj[C]),
                                               0.5 * (rhoi + Pj[RHO]), alpha1, alpha2, epsilon)
                    visc = viscous_acceleration_pair(m_j, pi_ij, 1.0)  # 0 if receding
                    w0 += visc * g0
                    w1 += visc * g1
                    w2 += visc * g2
                    if not same_body:
                        f0 += visc * g0
                        f1 += visc * g1
                        f2 += visc * g2
                    de_v += viscous_heating_pair(m_j, pi_ij, vg)
                # A_i applied to the regrouped sums
                G = (G0, G1, G2)
                acc = (a0, a1, a2)
                kc = (k0, k1, k2)
                wv = (w0, w1, w2)
                fv = (f0, f1, f2)
                Lt = ((L00, L01, L02), (L10, L11, L12), (L20, L21, L22))
                Tt = ((T00, T01, T02), (T10, T11, T12), (T20, T21, T22))
                m_i = Pi_[M]
                de_s = de_contact
                for a in range(dim):
                    s = acc[a] + kc[a]
                    for b in range(dim):
                        A_ab = Pi_[SYM[a][b]]
                        s += A_ab * G[b]
                        de_s -= A_ab * Tt[a][b]
                        L[a, b] = Lt[a][b]
                    dv[i, a] = s + wv[a]
                    P[p, U + a] = wv[a]
                    if track_contact:
                        contact_force[i, a] = m_i * (kc[a] + fv[a])
                drho[i] = rhoi * cont
                de[i] = de_s + de_v
                de_visc[i] = de_v
                pair_count[i] = count
                jaumann_stress_rate(L, S[i], shear, dS[i])

    @nb.njit(parallel=True, cache=True)
    def correction_pass(n_active, order, P, offsets, indices, h_ratio, variant,
                        energy_mode, dv_corr, de_corr, dv, de, chunk_size):
        """Pass 4 (AC only): ``-u_corr_i`` (eqs 33-36) and its energy term for every active
        particle ``i = order[p]``, from the viscous accelerations ``u`` that pass 2 (evaluated
        with (1, 1)) left in the packed records; neighbours of the same body within ``2 h_c``,
        ``h_c = h_ratio h``.  Adds them to the totals ``dv``, ``de``."""
        n = order.shape[0]
        n_chunks = (n + chunk_size - 1) // chunk_size
        for chunk in nb.prange(n_chunks):
            for p in range(chunk * chunk_size, min((chunk + 1) * chunk_size, n)):
                i = order[p]
                if i < n_active:
                    Pi_ = P[p]
                    u0 = u1 = u2 = 0.0
                    weight_sum = 0.0
                    paper_energy = 0.0
                    h_i = Pi_[H]
                    self_weight = correction_weight(Pi_[VOL], 0.0, h_ratio * h_i, dim)
                    for k in range(offsets[p], offsets[p + 1]):
                        q = indices[k]
                        Pj = P[q]
                        # distance first: most neighbours lie beyond 2 h_c, and position and
                        # h share the record's first cache line
                        h_c = h_ratio * 0.5 * (h_i + Pj[H])
                        r2 = 0.0
                        for a in range(dim):
                            d = Pi_[X + a] - Pj[X + a]
                            r2 += d * d
                        if r2 >= 4.0 * h_c * h_c or Pj[BODY] != Pi_[BODY]:
                            continue
                        w = correction_weight(Pj[VOL], math.sqrt(r2), h_c, dim)
                        weight_sum += w
                        u0 += w * Pj[U]
                        if dim > 1:
                            u1 += w * Pj[U + 1]
                        if dim > 2:
                            u2 += w * Pj[U + 2]
                        for a in range(dim):
                            paper_energy += 0.5 * w * (Pi_[V + a] - Pj[V + a]) * Pj[U + a]
                    weighted_u = (u0, u1, u2)
                    work = 0.0
                    for a in range(dim):
                        net = corrected_viscous_acceleration(Pi_[U + a], self_weight,
                                                             weight_sum,
                                                             weighted_u[a], variant)
                        dv_corr[i, a] = net - Pi_[U + a]
                        work -= Pi_[V + a] * dv_corr[i, a]
                    de_corr[i] = correction_energy_rate(work, paper_energy, weight_sum,
                                                        self_weight, variant, energy_mode)
                    for a in range(dim):
                        dv[i, a] += dv_corr[i, a]
                    de[i] += de_corr[i]

    return particle_pass, pair_pass, correction_pass


class CpuRates:
    """The rate passes on the CPU (numba, threads): fills a :class:`RateBuffers`.

    A backend has one method, :meth:`evaluate`; :class:`impactsph.gpu.GpuRates` is the
    other one, with the same signature and the same results."""

    device = "cpu"

    def __init__(self, dim: int):
        self.dim = dim
        self._passes = rate_kernels(dim)
        self._packed: np.ndarray | None = None  # the packed particle records, see pass 1
        self._chunk: tuple[int, int] | None = None  # (rows, particles per work item)

    def evaluate(self, n_active: int, arrays: tuple, table: np.ndarray, neighbours,
                 alpha1: float, alpha2: float, epsilon: float, correction: tuple | None,
                 b: RateBuffers) -> None:
        """Rates of the first ``n_active`` rows of ``arrays = (x, v, rho, e, S, m, h,
        material, body)`` (all rows, ghosts included, take part in the sums) into ``b``:
        ``drho``, the total accelerations ``dv`` and specific-energy rates ``de``, the
        viscous heating ``de_visc``,
        ``contact_force, pair_count, dS`` (pass 2) and,
        when ``correction = (h_ratio, variant, energy_mode)`` is given, ``dv_corr, de_corr``
        (pass 4)."""
        x, v, rho, e, S, m, h, material, body = arrays
        particle_pass, pair_pass, correction_pass = self._passes
        nl = neighbours
        n = x.shape[0]
        if self._packed is None or self._packed.shape[0] != n:
            self._packed = np.empty((n, packed_layout(self.dim)["width"]))
        particle_pass(nl.order, x, v, m, rho, e, S, h, body, material, table, self._packed)
        if self._chunk is None or self._chunk[0] != n:  # get_num_threads takes a lock
            self._chunk = (n, chunk_size(n))
        chunk = self._chunk[1]
        pair_pass(n_active, nl.order, self._packed, nl.offsets, nl.indices, alpha1, alpha2,
                  epsilon, S, material, table, b.drho, b.dv, b.de, b.de_visc,
                  b.contact_force, b.pair_count, b.dS, chunk)
        if correction is not None:
            h_ratio, variant, energy_mode = correction
            correction_pass(n_active, nl.order, self._packed, nl.offsets, nl.indices,
                            h_ratio, variant, energy_mode, b.dv_corr,
                            b.de_corr, b.dv, b.de, chunk)


@nb.njit(parallel=True, cache=True)
def pressures(rho, e, material, table, out):
    """``out[i]``: the pressure of particle ``i`` from its material's EOS (Pa)."""
    for i in nb.prange(rho.shape[0]):
        out[i] = material_pressure(table, material[i], rho[i], e[i])
    return out


def correction_only(x: np.ndarray, v: np.ndarray, m: np.ndarray, rho: np.ndarray,
                    h: np.ndarray, body: np.ndarray, neighbours, u: np.ndarray,
                    h_ratio: float, variant: int, energy_mode: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Pass 4 alone on given fields: ``(dv_corr, de_corr)`` for viscous accelerations ``u``
    (all particles active).  For tests and analysis; the solver runs it inside
    :meth:`CpuRates.evaluate`."""
    n, dim = x.shape
    lay = packed_layout(dim)
    order = neighbours.order
    packed = np.zeros((n, lay["width"]))
    packed[:, lay["x"]:lay["x"] + dim] = x[order]
    packed[:, lay["v"]:lay["v"] + dim] = v[order]
    packed[:, lay["h"]] = h[order]
    packed[:, lay["m"]] = m[order]
    packed[:, lay["volume"]] = (m / rho)[order]
    packed[:, lay["rho"]] = rho[order]
    packed[:, lay["body"]] = body[order]
    packed[:, lay["u"]:lay["u"] + dim] = u[order]
    dv_corr, de_corr = np.zeros((n, dim)), np.zeros(n)
    rate_kernels(dim)[2](n, order, packed, neighbours.offsets, neighbours.indices, h_ratio,
                         variant, energy_mode, dv_corr, de_corr, np.zeros((n, dim)),
                         np.zeros(n), chunk_size(n))
    return dv_corr, de_corr


class RateBuffers:
    """Output arrays of one rate evaluation, allocated once per run.  The contact force has
    a row per particle only where there is contact (several bodies, or walls), and the AC
    terms only with AC: otherwise they have no rows."""

    def __init__(self, n: int, dim: int, contact: bool = True, corrected: bool = True):
        self.drho = np.zeros(n)
        self.dv = np.zeros((n, dim))
        self.de = np.zeros(n)
        self.de_visc = np.zeros(n)
        self.dS = np.zeros((n, 3, 3))
        self.contact_force = np.zeros((n if contact else 0, dim))
        self.pair_count = np.zeros(n, dtype=np.int32)
        self.dv_corr = np.zeros((n if corrected else 0, dim))
        self.de_corr = np.zeros(n if corrected else 0)
