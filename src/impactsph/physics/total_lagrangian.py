"""The total-Lagrangian (TL) SPH passes: kernel and neighbours of the reference configuration,
deformation gradient, first Piola-Kirchhoff stress (docs/stabilisation.md, "Total-Lagrangian
formulation").

Sources: Bonet & Lok (1999) CMAME 180:97 (the corrected gradient); Vignjevic, Reveles &
Campbell (2006) CMES 14:181 (TLSPH); Ganzenmueller (2015) CMAME 286:87 (TLSPH as in LAMMPS
SMD, with its hourglass control).  Notation: ``X`` reference positions (t = 0), ``x``
current; ``V0_j = m_j / rho0_j``; ``R_ij = X_i - X_j``; ``grad0 W_ij = W'(|R_ij|, h_ij)
R_ij / |R_ij|`` (the cubic spline of :mod:`impactsph.kernels`, ``h_ij`` the pair mean).  The
neighbours of a particle are those of its body within the kernel's support at t = 0, for the
whole run.

Per particle (:func:`deformation_pass`)::

    (TL-1) M_i    = sum_j V0_j (X_j - X_i) (x) grad0 W_ij        reference moment matrix
           K_i    = M_i^-1         (Bonet-Lok: sum_j V0_j (X_j - X_i) (x) K_i^T grad0 W_ij = I)
    (TL-2) F_i    = sum_j V0_j (x_j - x_i) (x) grad0 W_ij  K_i     deformation gradient
    (TL-3) Fdot_i = sum_j V0_j (v_j - v_i) (x) grad0 W_ij  K_i     its rate
    (TL-4) L_i = Fdot_i F_i^-1,  J_i = det F_i
           drho_i/dt = -rho_i tr L_i,  dS_i/dt: the Jaumann rate of L_i (eqs 14-16)
    (TL-5) sigma_i = -(1 - D_i [p_i < 0]) p_i I + (1 - D_i) S_i    (the damage, as the UL
           passes apply it), P_i = J_i sigma_i F_i^-T   first Piola-Kirchhoff
    (TL-6) de_i/dt = P_i : Fdot_i / rho0_i       (= sigma : D / rho with rho = rho0 / J)

and per pair (:func:`force_pass`)::

    (TL-7) m_i dv_i/dt = sum_j V0_i V0_j (P_i K_i^T + P_j K_j^T) grad0 W_ij

(TL-7) is minus the derivative of ``sum_i V0_i psi(F_i)`` with respect to ``x_i`` for the
discrete F of (TL-2) (Bonet & Lok 1999, section 4), so its power is minus the sum of (TL-6):
the semi-discrete equations keep the total energy exactly, and the pair force is
antisymmetric (momentum kept to round-off).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

import numba as nb
import numpy as np

from impactsph.jitcache import njit_variant
from impactsph.kernels import cubic_spline, cubic_spline_gradient_factor
from impactsph.materials import RHO0, SHEAR, WAVE_MODULUS, YOUNGS
from impactsph.models.viscosity.monaghan import monaghan_viscosity
from impactsph.physics.stress_rate import jaumann_stress_rate_nd

#: a reference moment matrix whose determinant is below this (its eigenvalues' geometric mean
#: below 0.05: a particle with one or two neighbours) is not inverted: the particle is refused
#: (:func:`reference_setup` flags it)
SINGULAR_MOMENT = 0.05
#: particles per work item of the parallel passes (each item allocates its scratch once)
CHUNK = 64


@nb.njit(inline="always", cache=True)
def invert(A, out) -> float:
    """``out = A^-1`` for a 1x1, 2x2 or 3x3 matrix; returns ``det A`` (``out`` is left
    undefined when it is 0)."""
    dim = A.shape[0]
    if dim == 1:
        det = A[0, 0]
        if det != 0.0:
            out[0, 0] = 1.0 / det
        return det
    if dim == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        if det != 0.0:
            s = 1.0 / det
            out[0, 0] = A[1, 1] * s
            out[0, 1] = -A[0, 1] * s
            out[1, 0] = -A[1, 0] * s
            out[1, 1] = A[0, 0] * s
        return det
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    if det != 0.0:
        s = 1.0 / det
        out[0, 0] = c00 * s
        out[1, 0] = c01 * s
        out[2, 0] = c02 * s
        out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * s
        out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * s
        out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * s
        out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * s
        out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * s
        out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * s
    return det


@nb.njit(inline="always", cache=True)
def pair_gradient_sum(field, i, offsets, neighbours, V0, grad, K, raw, out, dim) -> None:
    """(TL-2)/(TL-3): ``out = (sum_j V0_j (f_j - f_i) (x) grad0 W_ij) K_i`` for the vector
    field ``f`` (positions: F; velocities: Fdot) of ``dim`` components, ``raw`` scratch."""
    for a in range(dim):
        for b in range(dim):
            raw[a, b] = 0.0
    for k in range(offsets[i], offsets[i + 1]):
        j = neighbours[k]
        for a in range(dim):
            d = V0[j] * (field[j, a] - field[i, a])
            for b in range(dim):
                raw[a, b] += d * grad[k, b]
    for a in range(dim):
        for b in range(dim):
            s = 0.0
            for c in range(dim):
                s += raw[a, c] * K[i, c, b]
            out[a, b] = s


@nb.njit(parallel=True, cache=True)
def reference_setup(X, V0, h, offsets, neighbours, grad, w, dw, K, det):  # pragma: no cover
    """Once, at t = 0: per pair ``grad0 W_ij`` (``grad``), ``W_ij`` (``w``) and
    ``W'(|R_ij|)`` (``dw``), per particle ``K_i = M_i^-1`` of (TL-1) and ``det M_i``
    (``det``; ``K_i`` is the identity where it is below :data:`SINGULAR_MOMENT` ** dim)."""
    n, dim = X.shape
    for i in nb.prange(n):
        M = np.zeros((dim, dim))
        Ki = np.empty((dim, dim))
        for k in range(offsets[i], offsets[i + 1]):
            j = neighbours[k]
            r2 = 0.0
            for a in range(dim):
                d = X[i, a] - X[j, a]
                r2 += d * d
            r = math.sqrt(r2)
            h_ij = 0.5 * (h[i] + h[j])
            inv_h = 1.0 / h_ij
            f = cubic_spline_gradient_factor(r * inv_h, inv_h, dim) if r > 0.0 else 0.0
            w[k] = cubic_spline(r, h_ij, dim)
            dw[k] = f * r
            for a in range(dim):
                grad[k, a] = f * (X[i, a] - X[j, a])
            for a in range(dim):
                d = V0[j] * (X[j, a] - X[i, a])
                for b in range(dim):
                    M[a, b] += d * grad[k, b]
        det[i] = invert(M, Ki)
        good = det[i] > SINGULAR_MOMENT ** dim
        for a in range(dim):
            for b in range(dim):
                K[i, a, b] = Ki[a, b] if good else (1.0 if a == b else 0.0)


@nb.njit(inline="always", cache=True)
def deform_particle(i, x, v, V0, m, rho, pressure, S, damage, material, table, offsets,
                    neighbours, grad, K, F, Fdot, Q, drho, dS, de, raw, Fi, Fd, Finv, L, Pk,
                    dim):
    """:func:`deformation_pass` for particle ``i`` (``raw`` to ``Pk``: scratch; ``dim`` a
    compile-time constant of the caller, so that the small loops unroll)."""
    pair_gradient_sum(x, i, offsets, neighbours, V0, grad, K, raw, Fi, dim)
    pair_gradient_sum(v, i, offsets, neighbours, V0, grad, K, raw, Fd, dim)
    J = invert(Fi, Finv)
    if J <= 0.0:  # an inverted particle: no stress, no rates; the survey stops the run
        J = 0.0
        for a in range(dim):
            for b in range(dim):
                Finv[a, b] = 0.0
    trace = 0.0
    for a in range(dim):
        for b in range(dim):
            s = 0.0
            for c in range(dim):
                s += Fd[a, c] * Finv[c, b]
            L[a, b] = s
        trace += L[a, a]
    k = material[i]
    drho[i] = -rho[i] * trace
    jaumann_stress_rate_nd(L, S[i], table[k, SHEAR], dS[i], dim)
    intact = 1.0 - damage[i]
    p = pressure[i] * intact if pressure[i] < 0.0 else pressure[i]
    # P = J sigma F^-T: Pk[a, b] = J sum_c sigma[a, c] Finv[b, c]
    power = 0.0
    for a in range(dim):
        for b in range(dim):
            s = 0.0
            for c in range(dim):
                sigma = intact * S[i, a, c] - (p if a == c else 0.0)
                s += sigma * Finv[b, c]
            Pk[a, b] = J * s
            power += Pk[a, b] * Fd[a, b]
    rho0 = m[i] / V0[i]
    de[i] = power / rho0
    for a in range(dim):
        for b in range(dim):
            F[i, a, b] = Fi[a, b]
            Fdot[i, a, b] = Fd[a, b]
            s = 0.0
            for c in range(dim):
                s += Pk[a, c] * K[i, b, c]
            Q[i, a, b] = s


@nb.njit(inline="always", cache=True)
def pair_error(G, y, X, x, i, j, inv_r, dim) -> float:
    """``((G_i + G_j) X_ij - 2 y_ij) . e`` with ``X_ij = X_j - X_i``, ``y_ij = y_j - y_i`` and
    ``e = (x_j - x_i) inv_r``: the pair's error against the two particles' linear predictions
    (``G = F``, ``y = x``: :func:`hourglass_pair`'s ``delta``; ``G = Fdot``, ``y = v``: its
    rate, the direction held)."""
    error = 0.0
    for a in range(dim):
        pred = 0.0
        for b in range(dim):
            pred += (G[i, a, b] + G[j, a, b]) * (X[j, b] - X[i, b])
        error += (pred - 2.0 * (y[j, a] - y[i, a])) * (x[j, a] - x[i, a]) * inv_r
    return error


@nb.njit(inline="always", cache=True)
def hourglass_pair(alpha, youngs, V0i, V0j, w0, X, x, F, i, j, out, dim, v, Fdot,
                   tau) -> float:
    """Ganzenmueller's (2015, section 3) hourglass penalty of the pair ``ij`` on ``i`` into
    ``out``, returns its magnitude: with ``X_ij = X_j - X_i``, ``x_ij = x_j - x_i`` and the
    error of each particle's linear prediction ``eps_ij^i = F_i X_ij - x_ij`` projected on the
    current direction ``e = x_ij / |x_ij|``::

        delta_ij = (eps_ij^i - eps_ji^j) . e = ((F_i + F_j) X_ij - 2 x_ij) . e
        f_i = -alpha/2 E V0_i V0_j W_ij / |X_ij|^2 (delta_ij + tau_ij ddelta_ij/dt) e,
        f_j = -f_i,     ddelta_ij/dt = ((Fdot_i + Fdot_j) X_ij - 2 v_ij) . e

    (N, or N/m in 2D).  A linear field gives ``delta = 0`` (no force); a zig-zag mode, which
    the collocated F of (TL-2) cannot see, is pulled back with a spring about ``alpha`` times
    the material's own stiffness.  ``tau`` (s) adds a dashpot on the same error's rate
    (``stabilisation.tl_hourglass_damping``: ``tau_ij = 2 zeta / omega_ij``, 0 for
    Ganzenmueller's spring alone); a linear velocity field gives ``ddelta/dt = 0`` too (the
    direction's own rate is left out).  ``dim``: the caller's compile-time dimension."""
    R2 = 0.0
    r2 = 0.0
    for a in range(dim):
        R2 += (X[j, a] - X[i, a]) ** 2
        r2 += (x[j, a] - x[i, a]) ** 2
    if r2 == 0.0 or R2 == 0.0:
        for a in range(dim):
            out[a] = 0.0
        return 0.0
    inv_r = 1.0 / math.sqrt(r2)
    delta = pair_error(F, x, X, x, i, j, inv_r, dim)
    if tau > 0.0:
        delta += tau * pair_error(Fdot, v, X, x, i, j, inv_r, dim)
    coef = -0.5 * alpha * youngs * V0i * V0j * w0 / R2 * delta
    for a in range(dim):
        out[a] = coef * (x[j, a] - x[i, a]) * inv_r
    return coef


@nb.njit(inline="always", cache=True)
def force_particle(i, x, v, X, V0, m, h, rho, material, table, offsets, neighbours, grad, w,
                   dw, F, Q, visc, alpha, dv, de, de_visc, acc, fh, dim, Fdot, tau):
    """:func:`force_pass` for particle ``i`` (``acc``, ``fh``: scratch; ``dim`` as in
    :func:`deform_particle`)."""
    a1, a2, eps = visc[0], visc[1], visc[2]
    for a in range(dim):
        acc[a] = 0.0
    heat = 0.0
    hg_power = 0.0
    ki = material[i]
    ci = math.sqrt(table[ki, WAVE_MODULUS] / rho[i])
    for k in range(offsets[i], offsets[i + 1]):
        j = neighbours[k]
        # (TL-7): (Q_i + Q_j) grad0 W_ij, times V0_i V0_j / m_i below
        for a in range(dim):
            s = 0.0
            for b in range(dim):
                s += (Q[i, a, b] + Q[j, a, b]) * grad[k, b]
            acc[a] += V0[j] * s * V0[i] / m[i]
        r2 = 0.0
        vr = 0.0
        for a in range(dim):
            d = x[i, a] - x[j, a]
            r2 += d * d
            vr += d * (v[i, a] - v[j, a])
        if vr < 0.0 and r2 > 0.0:
            h_ij = 0.5 * (h[i] + h[j])
            cj = math.sqrt(table[material[j], WAVE_MODULUS] / rho[j])
            pi_ij = monaghan_viscosity(vr, r2, h_ij, 0.5 * (ci + cj),
                                       0.5 * (rho[i] + rho[j]), a1, a2, eps)
            g = dw[k] / math.sqrt(r2)  # g_ij = g r_ij
            for a in range(dim):
                acc[a] -= m[j] * pi_ij * g * (x[i, a] - x[j, a])
            heat += 0.5 * m[j] * pi_ij * g * vr
        if alpha > 0.0:
            youngs = 0.5 * (table[ki, YOUNGS] + table[material[j], YOUNGS])
            hourglass_pair(alpha, youngs, V0[i], V0[j], w[k], X, x, F, i, j, fh, dim, v, Fdot,
                           0.5 * (tau[i] + tau[j]))
            for a in range(dim):
                acc[a] += fh[a] / m[i]
                hg_power += fh[a] * (v[i, a] - v[j, a])
    for a in range(dim):
        dv[i, a] = acc[a]
    de_visc[i] = heat
    de[i] += heat - 0.5 * hg_power / m[i]


@functools.cache
def compiled_passes(dim: int) -> SimpleNamespace:
    """:func:`deformation_pass` and :func:`force_pass` compiled for ``dim`` (1, 2 or 3), a
    constant in their code, so that the small ``dim`` x ``dim`` loops unroll (with
    ``x.shape[1]`` they stayed loops).  Each parallel work item is a chunk of :data:`CHUNK`
    particles that allocates its scratch once: an allocation per particle cost more than the
    particle's arithmetic."""

    @njit_variant(f"{dim}d", parallel=True)
    def deformation(n_active, x, v, V0, m, rho, pressure, S, damage, material, table, offsets,
                    neighbours, grad, K, F, Fdot, Q, drho, dS, de):  # pragma: no cover
        for chunk in nb.prange((n_active + CHUNK - 1) // CHUNK):
            raw = np.empty((dim, dim))
            Fi = np.empty((dim, dim))
            Fd = np.empty((dim, dim))
            Finv = np.empty((dim, dim))
            L = np.empty((dim, dim))
            Pk = np.empty((dim, dim))
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                deform_particle(i, x, v, V0, m, rho, pressure, S, damage, material, table,
                                offsets, neighbours, grad, K, F, Fdot, Q, drho, dS, de, raw, Fi,
                                Fd, Finv, L, Pk, dim)

    @njit_variant(f"{dim}d", parallel=True)
    def force(n_active, x, v, X, V0, m, h, rho, material, table, offsets, neighbours, grad, w,
              dw, F, Q, visc, alpha, dv, de, de_visc, Fdot, tau):  # pragma: no cover
        for chunk in nb.prange((n_active + CHUNK - 1) // CHUNK):
            acc = np.empty(dim)
            fh = np.empty(dim)
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                force_particle(i, x, v, X, V0, m, h, rho, material, table, offsets, neighbours,
                               grad, w, dw, F, Q, visc, alpha, dv, de, de_visc, acc, fh, dim,
                               Fdot, tau)

    return SimpleNamespace(deformation_pass=deformation, force_pass=force)


def deformation_pass(n_active, x, v, V0, m, rho, pressure, S, damage, material, table,
                     offsets, neighbours, grad, K, F, Fdot, Q, drho, dS, de) -> None:
    """(TL-2) to (TL-6) for every active particle: ``F``, ``Fdot``, ``Q_i = P_i K_i^T`` (the
    stress that (TL-7) applies to ``grad0 W_ij``), ``drho``, ``dS`` (the deviator's rate as its
    six components, ``(n, 6)``: :func:`impactsph.physics.stress_rate.jaumann_stress_rate`) and
    the stress power's ``de``; ``pressure`` from the equations of state (undamaged)."""
    compiled_passes(x.shape[1]).deformation_pass(
        n_active, x, v, V0, m, rho, pressure, S, damage, material, table, offsets, neighbours,
        grad, K, F, Fdot, Q, drho, dS, de)


def force_pass(n_active, x, v, X, V0, m, h, rho, material, table, offsets, neighbours, grad,
               w, dw, F, Q, visc, alpha, dv, de, de_visc, Fdot, tau) -> None:
    """(TL-7), the artificial viscosity and the hourglass penalty for every active particle:
    sets ``dv`` and ``de_visc``, adds to ``de``.

    Artificial viscosity: Monaghan's ``Pi_ij`` (eqs 29-30, ``visc = (alpha1, alpha2,
    epsilon)``) from the current separation ``r_ij = x_i - x_j`` of the reference pair, on
    the reference kernel's slope along the current direction, ``g_ij = W'(|R_ij|) r_ij /
    |r_ij|`` (as LAMMPS SMD's TLSPH)::

        dv_i/dt -= sum_j m_j Pi_ij g_ij,      de_i/dt += 1/2 sum_j m_j Pi_ij v_ij . g_ij

    antisymmetric, its power exactly the heating.  Hourglass penalty (``alpha`` > 0):
    :func:`hourglass_pair`, its power shared by the pair and taken from their internal
    energies, ``de_i/dt -= 1/2 f_i . (v_i - v_j) / m_i``, so the total energy is kept and a
    rigid translation is not heated.  ``Fdot`` and ``tau`` (per particle, s; zeros for none):
    the penalty's dashpot (:func:`hourglass_pair`)."""
    compiled_passes(x.shape[1]).force_pass(
        n_active, x, v, X, V0, m, h, rho, material, table, offsets, neighbours, grad, w, dw, F,
        Q, visc, alpha, dv, de, de_visc, Fdot, tau)


def reference_pairs(X: np.ndarray, h: np.ndarray, body: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The reference neighbour list in particle order (CSR: the neighbours of ``i`` are
    ``neighbours[offsets[i]:offsets[i + 1]]``): the pairs of the same body with ``|X_i -
    X_j| < 2 h_ij``, found once (``impactsph.neighbours.NeighbourList``)."""
    from impactsph.kernels import SUPPORT_RADIUS
    from impactsph.neighbours import NeighbourList, particle_order_list

    nl = NeighbourList.build(X, SUPPORT_RADIUS * float(h.max()), 0.0)
    rows, cols = nl.particle_pairs()
    r = np.linalg.norm(X[rows] - X[cols], axis=1)
    keep = (body[rows] == body[cols]) & (r < SUPPORT_RADIUS * 0.5 * (h[rows] + h[cols]))
    return particle_order_list(rows[keep], cols[keep], X.shape[0])


def reference_volumes(m: np.ndarray, material: np.ndarray, table: np.ndarray) -> np.ndarray:
    """``V0_i = m_i / rho0_i`` with the material's reference density (m^3, m^2 in 2D)."""
    return m / table[material, RHO0]


def reference(X: np.ndarray, V0: np.ndarray, h: np.ndarray, body: np.ndarray
              ) -> SimpleNamespace:
    """Everything of the reference configuration: ``offsets, neighbours`` (CSR), per pair
    ``grad, w, dw``, per particle ``K`` and ``det`` (of ``M_i``)."""
    X = np.ascontiguousarray(X, dtype=np.float64)
    offsets, neighbours = reference_pairs(X, h, body)
    n_pairs, (n, dim) = neighbours.shape[0], X.shape
    ref = SimpleNamespace(X=X.copy(), V0=V0, offsets=offsets, neighbours=neighbours,
                          grad=np.zeros((n_pairs, dim)), w=np.zeros(n_pairs),
                          dw=np.zeros(n_pairs), K=np.zeros((n, dim, dim)), det=np.zeros(n))
    reference_setup(ref.X, V0, h, offsets, neighbours, ref.grad, ref.w, ref.dw, ref.K, ref.det)
    return ref


