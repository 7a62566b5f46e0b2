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
import warnings
from types import SimpleNamespace

import numba as nb
import numpy as np

from impactsph.jitcache import njit_variant, noalias_option
from impactsph.kernels import cubic_spline, cubic_spline_gradient_factor
from impactsph.materials import RHO0, SHEAR, WAVE_MODULUS
from impactsph.models.viscosity.monaghan import monaghan_viscosity
from impactsph.physics.borrow import borrowed
from impactsph.physics.chunked import SIMPLIFICATIONS_ONLY, run_chunked, threads_for
from impactsph.physics.stress_rate import jaumann_stress_rate_nd

#: a reference moment matrix whose determinant is below this (its eigenvalues' geometric mean
#: below 0.05: a particle with one or two neighbours) is not inverted: the particle is refused
#: (:func:`reference_setup` flags it)
SINGULAR_MOMENT = 0.05
#: particles per work item of the deformation pass (each item allocates its scratch once)
CHUNK = 64
#: the passes' floating-point flags, ``impactsph.physics.passes.PAIR_FASTMATH``'s:
#: reassociation, so that LLVM can vectorise their loops over the neighbours (the sums run as
#: partial sums, one per vector lane), and fused multiply-adds; run in shares of their chunks
#: (no ``prange``), each pass is one compiled code, so neither flag makes a compiling process
#: and a loading one differ (:mod:`impactsph.physics.chunked`)
PASS_FASTMATH = {"reassoc", "arcp", "nsz", "contract"}
#: the passes' compile options: run in shares of their chunks (``nogil``), their
#: distinct arrays marked ``noalias`` as a ``prange`` body's were
#: (:func:`impactsph.jitcache.noalias_option`)
PASS_OPTIONS = {"nogil": True, "fastmath": PASS_FASTMATH, "error_model": "numpy",
                **noalias_option(), "parallel": SIMPLIFICATIONS_ONLY}
# (numba warns that those options found nothing to run in parallel: that is the point)
warnings.filterwarnings(
    "ignore", message=r"(?s)\s*The keyword argument 'parallel=True' was specified but no "
    r"transformation.*total_lagrangian\.py\", line \d+:.*def (deformation|force)\(")


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


@nb.njit(cache=True)
def vector(a, j, dim):
    """Row ``j`` of the ``(n, dim)`` array ``a`` as three numbers (0 past ``dim``)."""
    return (a[j, 0], a[j, 1] if dim > 1 else 0.0, a[j, 2] if dim > 2 else 0.0)


@nb.njit(cache=True)
def matrix(a, j, dim):
    """Matrix ``j`` of the ``(n, dim, dim)`` array ``a`` as nine numbers, row by row (0 past
    ``dim``)."""
    return (a[j, 0, 0], a[j, 0, 1] if dim > 1 else 0.0, a[j, 0, 2] if dim > 2 else 0.0,
            a[j, 1, 0] if dim > 1 else 0.0, a[j, 1, 1] if dim > 1 else 0.0,
            a[j, 1, 2] if dim > 2 else 0.0,
            a[j, 2, 0] if dim > 2 else 0.0, a[j, 2, 1] if dim > 2 else 0.0,
            a[j, 2, 2] if dim > 2 else 0.0)


@nb.njit(inline="always", cache=True)
def pair_gradient_sums(x, v, i, offsets, neighbours, V0, grad, K, F, Fdot, dim) -> None:
    """(TL-2) and (TL-3) in one sweep of the neighbours: ``F = (sum_j V0_j (x_j - x_i) (x)
    grad0 W_ij) K_i`` and ``Fdot`` the same of the velocities, into the ``dim`` x ``dim``
    ``F`` and ``Fdot``.  The sums are numbers, not a scratch array, so that they stay in
    registers and LLVM can vectorise the loop (under :data:`PASS_FASTMATH`)."""
    xi0, xi1, xi2 = vector(x, i, dim)
    vi0, vi1, vi2 = vector(v, i, dim)
    x00 = x01 = x02 = x10 = x11 = x12 = x20 = x21 = x22 = 0.0
    v00 = v01 = v02 = v10 = v11 = v12 = v20 = v21 = v22 = 0.0
    for k in range(offsets[i], offsets[i + 1]):
        j = neighbours[k]
        g0, g1, g2 = vector(grad, k, dim)
        xj0, xj1, xj2 = vector(x, j, dim)
        vj0, vj1, vj2 = vector(v, j, dim)
        V0j = V0[j]
        dx0, dx1, dx2 = V0j * (xj0 - xi0), V0j * (xj1 - xi1), V0j * (xj2 - xi2)
        dv0, dv1, dv2 = V0j * (vj0 - vi0), V0j * (vj1 - vi1), V0j * (vj2 - vi2)
        x00 += dx0 * g0
        x01 += dx0 * g1
        x02 += dx0 * g2
        x10 += dx1 * g0
        x11 += dx1 * g1
        x12 += dx1 * g2
        x20 += dx2 * g0
        x21 += dx2 * g1
        x22 += dx2 * g2
        v00 += dv0 * g0
        v01 += dv0 * g1
        v02 += dv0 * g2
        v10 += dv1 * g0
        v11 += dv1 * g1
        v12 += dv1 * g2
        v20 += dv2 * g0
        v21 += dv2 * g1
        v22 += dv2 * g2
    raw_x = ((x00, x01, x02), (x10, x11, x12), (x20, x21, x22))
    raw_v = ((v00, v01, v02), (v10, v11, v12), (v20, v21, v22))
    for a in range(dim):
        for b in range(dim):
            sx = 0.0
            sv = 0.0
            for c in range(dim):
                sx += raw_x[a][c] * K[i, c, b]
                sv += raw_v[a][c] * K[i, c, b]
            F[a, b] = sx
            Fdot[a, b] = sv


@nb.njit(parallel=True, cache=True)
def reference_setup(X, V0, h, offsets, neighbours, grad, w, dw, K, det):  # pragma: no cover
    """Once, at t = 0: per pair ``grad0 W_ij`` (``grad``), ``W_ij / |R_ij|^2`` (``w``, 1/m^2
    times the kernel's units: the hourglass penalty's weight; 0 for coincident particles) and
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
            w[k] = cubic_spline(r, h_ij, dim) / r2 if r > 0.0 else 0.0
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
                    neighbours, grad, K, F, Fdot, Q, drho, dS, de, wave_speed, Fi, Fd, Finv, L,
                    Pk, dim):
    """:func:`deformation_pass` for particle ``i`` (``Fi`` to ``Pk``: scratch; ``dim`` a
    compile-time constant of the caller, so that the small loops unroll)."""
    pair_gradient_sums(x, v, i, offsets, neighbours, V0, grad, K, Fi, Fd, dim)
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
    wave_speed[i] = math.sqrt(table[k, WAVE_MODULUS] / rho[i])
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


@nb.njit(cache=True)
def pair_error(Gi, Gj, R, y, e):
    """``((G_i + G_j) X_ij - 2 y_ij) . e``, with ``R = X_ij = X_j - X_i``, ``y = y_ij = y_j -
    y_i`` and ``e`` the current unit direction ``(x_j - x_i) / |x_j - x_i|`` (each three
    numbers; ``G`` nine, row by row): the pair's error against the two particles' linear
    predictions (``G = F``, ``y = x``: :func:`hourglass_coefficient`'s ``delta``; ``G =
    Fdot``, ``y = v``: its rate, the direction held)."""
    error = 0.0
    for a in range(3):
        pred = ((Gi[3 * a] + Gj[3 * a]) * R[0] + (Gi[3 * a + 1] + Gj[3 * a + 1]) * R[1]
                + (Gi[3 * a + 2] + Gj[3 * a + 2]) * R[2])
        error += (pred - 2.0 * y[a]) * e[a]
    return error


@nb.njit(cache=True)
def hourglass_coefficient(alpha, youngs, V0i, V0j, w0_over_R2, delta) -> float:
    """Ganzenmueller's (2015, section 3) hourglass penalty of the pair ``ij``: the force on
    ``i`` is this times ``e``.  With ``X_ij = X_j - X_i``, ``x_ij = x_j - x_i`` and the error
    of each particle's linear prediction ``eps_ij^i = F_i X_ij - x_ij`` projected on the
    current direction ``e = x_ij / |x_ij|``::

        delta_ij = (eps_ij^i - eps_ji^j) . e = ((F_i + F_j) X_ij - 2 x_ij) . e
        f_i = -alpha/2 E V0_i V0_j W_ij / |X_ij|^2 (delta_ij + tau_ij ddelta_ij/dt) e,
        f_j = -f_i,     ddelta_ij/dt = ((Fdot_i + Fdot_j) X_ij - 2 v_ij) . e

    (N, or N/m in 2D; ``delta`` here is the bracket).  A linear field gives ``delta = 0`` (no
    force); a zig-zag mode, which the collocated F of (TL-2) cannot see, is pulled back with a
    spring about ``alpha`` times the material's own stiffness.  ``tau`` (s) adds a dashpot on
    the same error's rate (``stabilisation.tl_hourglass_damping``: ``tau_ij = 2 zeta /
    omega_ij``, 0 for Ganzenmueller's spring alone); a linear velocity field gives
    ``ddelta/dt = 0`` too (the direction's own rate is left out)."""
    return -0.5 * alpha * youngs * V0i * V0j * w0_over_R2 * delta


@nb.njit(inline="always", cache=True)
def force_particle(i, x, v, X, V0, m, h, rho, wave_speed, youngs, offsets, neighbours, grad,
                   w_over_R2, dw, F, Q, visc, alpha, dv, de, de_visc, dim, Fdot, tau, dashpot):
    """:func:`force_pass` for particle ``i`` (``dim`` as in :func:`deform_particle`).  The
    particle's own columns are read once, each pair's as numbers (no scratch array, so the
    sums stay in registers); ``V0_i / m_i`` is applied to the stress sum once."""
    a1, a2, eps = visc[0], visc[1], visc[2]
    xi, vi, Xi = vector(x, i, dim), vector(v, i, dim), vector(X, i, dim)
    Qi = matrix(Q, i, dim)
    hi, ci, rhoi, V0i, Ei, taui = h[i], wave_speed[i], rho[i], V0[i], youngs[i], tau[i]
    stress0 = stress1 = stress2 = 0.0  # sum_j V0_j (Q_i + Q_j) grad0 W_ij
    visc0 = visc1 = visc2 = 0.0  # sum_j m_j Pi_ij g_ij
    hg0 = hg1 = hg2 = 0.0  # sum_j f_ij (the hourglass penalty)
    heat = 0.0
    hg_power = 0.0
    penalty = alpha > 0.0
    Fi, Fdi = matrix(F, i, dim), matrix(Fdot, i, dim)
    for k in range(offsets[i], offsets[i + 1]):
        j = neighbours[k]
        # (TL-7): (Q_i + Q_j) grad0 W_ij, times V0_i V0_j / m_i below
        g = vector(grad, k, dim)
        Qj = matrix(Q, j, dim)
        V0j = V0[j]
        stress0 += V0j * ((Qi[0] + Qj[0]) * g[0] + (Qi[1] + Qj[1]) * g[1]
                          + (Qi[2] + Qj[2]) * g[2])
        stress1 += V0j * ((Qi[3] + Qj[3]) * g[0] + (Qi[4] + Qj[4]) * g[1]
                          + (Qi[5] + Qj[5]) * g[2])
        stress2 += V0j * ((Qi[6] + Qj[6]) * g[0] + (Qi[7] + Qj[7]) * g[1]
                          + (Qi[8] + Qj[8]) * g[2])
        xj, vj = vector(x, j, dim), vector(v, j, dim)
        d0, d1, d2 = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]  # x_j - x_i
        u0, u1, u2 = vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]  # v_j - v_i
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        vr = d0 * u0 + d1 * u1 + d2 * u2  # v_ij . r_ij, both signs flipped
        # no branch in this loop (the vectoriser's condition): a pair at r = 0 gets no
        # viscosity and no penalty through inv_r = 0, a receding one no viscosity through
        # monaghan_viscosity's min(vr, 0)
        inv_r = 1.0 / math.sqrt(r2) if r2 > 0.0 else 0.0
        pi_ij = monaghan_viscosity(vr, r2, 0.5 * (hi + h[j]), 0.5 * (ci + wave_speed[j]),
                                   0.5 * (rhoi + rho[j]), a1, a2, eps)
        push = m[j] * pi_ij * dw[k] * inv_r  # m_j Pi_ij g_ij = push r_ij
        visc0 += push * d0  # -m_j Pi_ij g_ij, with r_ij = x_i - x_j = -d
        visc1 += push * d1
        visc2 += push * d2
        heat += 0.5 * push * vr
        if penalty:
            Xj = vector(X, j, dim)
            R = (Xj[0] - Xi[0], Xj[1] - Xi[1], Xj[2] - Xi[2])
            e = (d0 * inv_r, d1 * inv_r, d2 * inv_r)
            delta = pair_error(Fi, matrix(F, j, dim), R, (d0, d1, d2), e)
            if dashpot:
                delta += 0.5 * (taui + tau[j]) * pair_error(
                    Fdi, matrix(Fdot, j, dim), R, (u0, u1, u2), e)
            coef = hourglass_coefficient(alpha, 0.5 * (Ei + youngs[j]), V0i, V0j,
                                         w_over_R2[k], delta)
            f0, f1, f2 = coef * e[0], coef * e[1], coef * e[2]
            hg0 += f0
            hg1 += f1
            hg2 += f2
            hg_power -= f0 * u0 + f1 * u1 + f2 * u2  # f_ij . (v_i - v_j)
    own = V0i / m[i]
    inv_m = 1.0 / m[i]
    dv[i, 0] = stress0 * own + visc0 + hg0 * inv_m
    if dim > 1:
        dv[i, 1] = stress1 * own + visc1 + hg1 * inv_m
    if dim > 2:
        dv[i, 2] = stress2 * own + visc2 + hg2 * inv_m
    de_visc[i] = heat
    de[i] += heat - 0.5 * hg_power * inv_m


@functools.cache
def compiled_passes(dim: int) -> SimpleNamespace:
    """:func:`deformation_pass` and :func:`force_pass` compiled for ``dim`` (1, 2 or 3), a
    constant in their code, so that the small ``dim`` x ``dim`` loops unroll (with
    ``x.shape[1]`` they stayed loops).  Each work item is a chunk of :data:`CHUNK` particles
    that allocates its scratch once: an allocation per particle cost more than the particle's
    arithmetic.  The passes take ``(first, step, ...)`` and run share ``first`` of ``step`` of
    the chunks, the shares on numba's threads (:mod:`impactsph.physics.chunked`; a ``prange``
    loop under :data:`PASS_FASTMATH` gave the process that compiled it other bits than the
    processes that loaded it from numba's cache), with their arrays borrowed
    (:mod:`impactsph.physics.borrow`), as a threaded loop's body had them."""

    @njit_variant(f"{dim}d", **PASS_OPTIONS)
    def deformation(first, step, n_active, x, v, V0, m, rho, pressure, S, damage, material,
                    table, offsets, neighbours, grad, K, F, Fdot, Q, drho, dS, de,
                    wave_speed):  # pragma: no cover
        x = borrowed(x)
        v = borrowed(v)
        V0 = borrowed(V0)
        m = borrowed(m)
        rho = borrowed(rho)
        pressure = borrowed(pressure)
        S = borrowed(S)
        damage = borrowed(damage)
        material = borrowed(material)
        table = borrowed(table)
        offsets = borrowed(offsets)
        neighbours = borrowed(neighbours)
        grad = borrowed(grad)
        K = borrowed(K)
        F = borrowed(F)
        Fdot = borrowed(Fdot)
        Q = borrowed(Q)
        drho = borrowed(drho)
        dS = borrowed(dS)
        de = borrowed(de)
        wave_speed = borrowed(wave_speed)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
            Fi = np.empty((dim, dim))
            Fd = np.empty((dim, dim))
            Finv = np.empty((dim, dim))
            L = np.empty((dim, dim))
            Pk = np.empty((dim, dim))
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                deform_particle(i, x, v, V0, m, rho, pressure, S, damage, material, table,
                                offsets, neighbours, grad, K, F, Fdot, Q, drho, dS, de,
                                wave_speed, Fi, Fd, Finv, L, Pk, dim)

    @njit_variant(f"{dim}d", **PASS_OPTIONS)
    def force(first, step, n_active, x, v, X, V0, m, h, rho, wave_speed, youngs, offsets,
              neighbours, grad, w, dw, F, Q, visc, alpha, dv, de, de_visc, Fdot, tau,
              dashpot):  # pragma: no cover
        x = borrowed(x)
        v = borrowed(v)
        X = borrowed(X)
        V0 = borrowed(V0)
        m = borrowed(m)
        h = borrowed(h)
        rho = borrowed(rho)
        wave_speed = borrowed(wave_speed)
        youngs = borrowed(youngs)
        offsets = borrowed(offsets)
        neighbours = borrowed(neighbours)
        grad = borrowed(grad)
        w = borrowed(w)
        dw = borrowed(dw)
        F = borrowed(F)
        Q = borrowed(Q)
        dv = borrowed(dv)
        de = borrowed(de)
        de_visc = borrowed(de_visc)
        Fdot = borrowed(Fdot)
        tau = borrowed(tau)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
            for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_active)):
                force_particle(i, x, v, X, V0, m, h, rho, wave_speed, youngs, offsets,
                               neighbours, grad, w, dw, F, Q, visc, alpha, dv, de, de_visc,
                               dim, Fdot, tau, dashpot)

    return SimpleNamespace(deformation_pass=deformation, force_pass=force)


def deformation_pass(n_active, x, v, V0, m, rho, pressure, S, damage, material, table,
                     offsets, neighbours, grad, K, F, Fdot, Q, drho, dS, de,
                     wave_speed) -> None:
    """(TL-2) to (TL-6) for every active particle: ``F``, ``Fdot``, ``Q_i = P_i K_i^T`` (the
    stress that (TL-7) applies to ``grad0 W_ij``), ``drho``, ``dS`` (the deviator's rate as its
    six components, ``(n, 6)``: :func:`impactsph.physics.stress_rate.jaumann_stress_rate`),
    the stress power's ``de`` and the sound speed ``wave_speed = sqrt(M / rho)`` (``M`` the
    material's wave modulus; m/s) that :func:`force_pass`'s viscosity reads; ``pressure`` from
    the equations of state (undamaged)."""
    run_chunked(compiled_passes(x.shape[1]).deformation_pass, threads_for(n_active, CHUNK, True),
        n_active, x, v, V0, m, rho, pressure, S, damage, material, table, offsets, neighbours,
        grad, K, F, Fdot, Q, drho, dS, de, wave_speed)


def force_pass(n_active, x, v, X, V0, m, h, rho, wave_speed, youngs, offsets, neighbours,
               grad, w, dw, F, Q, visc, alpha, dv, de, de_visc, Fdot, tau, dashpot) -> None:
    """(TL-7), the artificial viscosity and the hourglass penalty for every active particle:
    sets ``dv`` and ``de_visc``, adds to ``de``.  ``wave_speed``: each particle's sound speed
    (:func:`deformation_pass`); ``youngs``: each particle's Young's modulus (Pa).

    Artificial viscosity: Monaghan's ``Pi_ij`` (eqs 29-30, ``visc = (alpha1, alpha2,
    epsilon)``) from the current separation ``r_ij = x_i - x_j`` of the reference pair, on
    the reference kernel's slope along the current direction, ``g_ij = W'(|R_ij|) r_ij /
    |r_ij|`` (as LAMMPS SMD's TLSPH)::

        dv_i/dt -= sum_j m_j Pi_ij g_ij,      de_i/dt += 1/2 sum_j m_j Pi_ij v_ij . g_ij

    antisymmetric, its power exactly the heating.  Hourglass penalty (``alpha`` > 0):
    :func:`hourglass_coefficient`, its power shared by the pair and taken from their internal
    energies, ``de_i/dt -= 1/2 f_i . (v_i - v_j) / m_i``, so the total energy is kept and a
    rigid translation is not heated.  ``Fdot`` and ``tau`` (per particle, s): the penalty's
    dashpot (:func:`hourglass_coefficient`), evaluated where ``dashpot`` is true (some ``tau``
    > 0: the caller knows it once for the run, so the pass does not test every pair)."""
    run_chunked(compiled_passes(x.shape[1]).force_pass, threads_for(n_active, CHUNK, True),
        n_active, x, v, X, V0, m, h, rho, wave_speed, youngs, offsets, neighbours, grad, w, dw,
        F, Q, visc, alpha, dv, de, de_visc, Fdot, tau, bool(dashpot))


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


