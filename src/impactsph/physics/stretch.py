"""A smoothing length that follows the local stretch (``kernel.max_stretch``; issue 11,
docs/stabilisation.md, "A kernel that follows the stretch").

Where a solid is squashed along one direction it is stretched along another: the foot of a
Taylor bar spreads along the wall to twice its radius, so its particles end up twice as far
apart along the wall (and, in 3D, round the axis) as they started, while they crowd together
along the axis.  A kernel of fixed ``h`` then has one neighbour or none along the stretched
direction.  At each neighbour-list build each particle's smoothing length is set to

    (ST-1)  h_i = h0_i clamp(lambda_i, 1, max_stretch)

with ``h0_i`` its smoothing length at t = 0 and ``lambda_i`` the largest principal stretch of
its neighbourhood's deformation gradient, the least-squares fit to its neighbours'
separations now and at t = 0 (same body, a symmetry plane's mirror images included, so that a
half or quarter model is the whole one; kernel-weighted with the current ``h_ij``; used here
only to size the kernel):

    (ST-2)  F_i = (sum_j w_ij x_ij (x) X_ij) (sum_j w_ij X_ij (x) X_ij)^-1
    (ST-3)  lambda_i = sqrt(largest eigenvalue of F_i F_i^T)

(``x_ij = x_j - x_i`` now, ``X_ij`` at t = 0, ``w_ij = W(|x_ij|, h_ij)``).  (ST-2) is exact
for any homogeneous deformation whatever the neighbours, at free surfaces too, and (ST-3) is
1 for any rigid motion.  A neighbourhood whose moment ``sum_j w_ij X_ij (x) X_ij`` is
singular (fewer neighbours than the dimension needs, or all on one line) keeps ``h0``.

It is an isotropic cousin of adaptive SPH (ASPH; Owen, Villumsen, Shapiro & Martel 1998,
ApJS 116:155), whose smoothing tensor follows the deformation in every direction: here the
kernel stays round and grows with the largest stretch only, so the pair terms keep their form.
Along the squashed direction it then reaches over more particles than before.

Pairs use the mean ``h_ij = (h_i + h_j) / 2`` as with a kernel width per body, so the pair
forces stay antisymmetric (momentum kept exactly) and the energy terms their power (energy
kept by the semi-discrete equations).  ``h`` changes only at a build, so the list (built with
the new ``h``) always covers every pair's support.
"""

from __future__ import annotations

import math
from functools import cache

import numba as nb
import numpy as np

from ..boundaries import SYMMETRY
from ..jitcache import njit_variant
from ..kernels import cubic_spline

#: a neighbourhood's moment matrix counts as singular below this share of its trace's power
SINGULAR = 1e-8


@nb.njit(inline="always", cache=True)
def _largest_eigenvalue_sym3(a00, a01, a02, a11, a12, a22):
    """The largest eigenvalue of a symmetric 3x3 matrix (the trigonometric form of the cubic's
    roots; Smith 1961)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    mean = (a00 + a11 + a22) / 3.0
    if p1 == 0.0:
        return max(a00, max(a11, a22))
    p2 = (a00 - mean) ** 2 + (a11 - mean) ** 2 + (a22 - mean) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - mean) / p, (a11 - mean) / p, (a22 - mean) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    half_det = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
                      + b02 * (b01 * b12 - b11 * b02))
    half_det = min(1.0, max(-1.0, half_det))
    return mean + 2.0 * p * math.cos(math.acos(half_det) / 3.0)


@nb.njit(inline="always", cache=True)
def _principal_stretch(A, B, dim, inv, F, C):
    """Largest principal stretch of ``F = A B^-1`` (``A``, ``B``: ``dim x dim``; ``B``
    symmetric), or -1 where ``B`` is singular; ``inv``, ``F``, ``C``: 3 x 3 scratch (the
    caller's: arrays on the CPU, a GPU thread's local arrays)."""
    if dim == 1:
        if B[0, 0] <= 0.0:
            return -1.0
        return abs(A[0, 0] / B[0, 0])
    trace = 0.0
    for a in range(dim):
        trace += B[a, a]
    if dim == 2:
        det = B[0, 0] * B[1, 1] - B[0, 1] * B[1, 0]
        if not det > SINGULAR * (trace / 2.0) ** 2:
            return -1.0
        i00, i01, i11 = B[1, 1] / det, -B[0, 1] / det, B[0, 0] / det
        f00 = A[0, 0] * i00 + A[0, 1] * i01
        f01 = A[0, 0] * i01 + A[0, 1] * i11
        f10 = A[1, 0] * i00 + A[1, 1] * i01
        f11 = A[1, 0] * i01 + A[1, 1] * i11
        c00 = f00 * f00 + f01 * f01
        c01 = f00 * f10 + f01 * f11
        c11 = f10 * f10 + f11 * f11
        half = 0.5 * (c00 + c11)
        return math.sqrt(half + math.sqrt(0.25 * (c00 - c11) ** 2 + c01 * c01))
    c00 = B[1, 1] * B[2, 2] - B[1, 2] * B[2, 1]
    c01 = B[0, 2] * B[2, 1] - B[0, 1] * B[2, 2]
    c02 = B[0, 1] * B[1, 2] - B[0, 2] * B[1, 1]
    det = B[0, 0] * c00 + B[1, 0] * c01 + B[2, 0] * c02
    if not det > SINGULAR * (trace / 3.0) ** 3:
        return -1.0
    inv[0, 0], inv[0, 1], inv[0, 2] = c00 / det, c01 / det, c02 / det
    inv[1, 0] = (B[1, 2] * B[2, 0] - B[1, 0] * B[2, 2]) / det
    inv[1, 1] = (B[0, 0] * B[2, 2] - B[0, 2] * B[2, 0]) / det
    inv[1, 2] = (B[0, 2] * B[1, 0] - B[0, 0] * B[1, 2]) / det
    inv[2, 0] = (B[1, 0] * B[2, 1] - B[1, 1] * B[2, 0]) / det
    inv[2, 1] = (B[0, 1] * B[2, 0] - B[0, 0] * B[2, 1]) / det
    inv[2, 2] = (B[0, 0] * B[1, 1] - B[0, 1] * B[1, 0]) / det
    # F = A B^-1 and C = F F^T written out: numba's matrix product needs SciPy's BLAS,
    # which is not a dependency
    for a in range(3):
        for b in range(3):
            F[a, b] = 0.0
            for c in range(3):
                F[a, b] += A[a, c] * inv[c, b]
    for a in range(3):
        for b in range(a, 3):
            C[a, b] = 0.0
            for c in range(3):
                C[a, b] += F[a, c] * F[b, c]
    return math.sqrt(max(_largest_eigenvalue_sym3(C[0, 0], C[0, 1], C[0, 2], C[1, 1],
                                                  C[1, 2], C[2, 2]), 0.0))


def principal_stretches(order, offsets, indices, x, x0, body, h, n_real) -> np.ndarray:
    """(ST-2, ST-3) for the particles ``0 .. n_real - 1`` over a neighbour list (sorted
    positions, as :class:`impactsph.neighbours.NeighbourList`): ``x``, ``x0``, ``body`` and
    ``h`` have a row per row of the list (ghosts after the real particles): the positions now
    and at t = 0, the body (a neighbour of another body is left out; so is a row whose body is
    negative) and the smoothing length now.  -1 where the neighbourhood's moment is
    singular."""
    dim = x.shape[1]
    if dim not in (1, 2, 3):
        raise ValueError(f"x has {dim} columns: the stretch is computed in 1, 2 or 3 dimensions")
    return _stretch_kernel(dim)(order, offsets, indices, x, x0, body, h, n_real)


@nb.njit(inline="always", cache=True)
def stretch_row(p, order, offsets, indices, x, x0, body, h, A, B, inv, F, C, dim):
    """(ST-2, ST-3) of the real particle at sorted position ``p`` of a neighbour list in
    ``dim`` dimensions: ``A``, ``B`` the ``dim x dim`` and ``inv``, ``F``, ``C`` the 3 x 3
    scratch of :func:`_principal_stretch` (arrays on the CPU, a GPU thread's local arrays:
    :mod:`impactsph.gpu_step` calls it too).  Inlined into a kernel whose ``dim`` is a
    compile-time constant (a closure's number), the sums of (ST-2) are scalars and the
    branches on ``dim`` fold away.  A module function, not a closure made per dimension: a
    kernel that held a compiled closure could not be found again in numba's cache (its key
    hashes the closure's contents, and a dispatcher pickles with an id of its process), so
    it compiled again in every process (1.3 s in 2D) and added an entry to the cache each time.
    """
    i = order[p]
    xi0 = x[i, 0]
    xi1 = x[i, 1] if dim > 1 else 0.0
    xi2 = x[i, 2] if dim > 2 else 0.0
    Xi0 = x0[i, 0]
    Xi1 = x0[i, 1] if dim > 1 else 0.0
    Xi2 = x0[i, 2] if dim > 2 else 0.0
    a00 = a01 = a02 = a10 = a11 = a12 = a20 = a21 = a22 = 0.0
    b00 = b01 = b02 = b10 = b11 = b12 = b20 = b21 = b22 = 0.0
    for k in range(offsets[p], offsets[p + 1]):
        j = order[indices[k]]
        if body[j] != body[i]:
            continue
        dx0 = x[j, 0] - xi0
        r2 = dx0 ** 2
        dx1 = dx2 = 0.0
        if dim > 1:
            dx1 = x[j, 1] - xi1
            r2 += dx1 ** 2
        if dim > 2:
            dx2 = x[j, 2] - xi2
            r2 += dx2 ** 2
        w = cubic_spline(math.sqrt(r2), 0.5 * (h[i] + h[j]), dim)
        if w == 0.0:
            continue
        dX0 = x0[j, 0] - Xi0
        dX1 = x0[j, 1] - Xi1 if dim > 1 else 0.0
        dX2 = x0[j, 2] - Xi2 if dim > 2 else 0.0
        a00 += w * dx0 * dX0
        b00 += w * dX0 * dX0
        if dim > 1:
            a01 += w * dx0 * dX1
            b01 += w * dX0 * dX1
            a10 += w * dx1 * dX0
            b10 += w * dX1 * dX0
            a11 += w * dx1 * dX1
            b11 += w * dX1 * dX1
        if dim > 2:
            a02 += w * dx0 * dX2
            b02 += w * dX0 * dX2
            a12 += w * dx1 * dX2
            b12 += w * dX1 * dX2
            a20 += w * dx2 * dX0
            b20 += w * dX2 * dX0
            a21 += w * dx2 * dX1
            b21 += w * dX2 * dX1
            a22 += w * dx2 * dX2
            b22 += w * dX2 * dX2
    A[0, 0] = a00
    B[0, 0] = b00
    if dim > 1:
        A[0, 1], A[1, 0], A[1, 1] = a01, a10, a11
        B[0, 1], B[1, 0], B[1, 1] = b01, b10, b11
    if dim > 2:
        A[0, 2], A[1, 2], A[2, 0], A[2, 1], A[2, 2] = a02, a12, a20, a21, a22
        B[0, 2], B[1, 2], B[2, 0], B[2, 1], B[2, 2] = b02, b12, b20, b21, b22
    return _principal_stretch(A, B, dim, inv, F, C)


@cache
def _stretch_kernel(dim: int):
    """:func:`principal_stretches` compiled for one dimension (a compile-time constant): the
    sums of (ST-2) in scalars, not in ``dim x dim`` arrays indexed in loops of a run-time
    length.  The same arithmetic in the same order, so the same bits; 1.4 times as fast (the
    3D Taylor cylinder's 2.1 million list entries: 19-20 ms against 28 ms on two threads)."""

    @njit_variant(f"{dim}d", parallel=True)
    def stretches(order, offsets, indices, x, x0, body, h, n_real):
        out = np.full(n_real, -1.0)
        for p in nb.prange(order.shape[0]):
            i = order[p]
            if i >= n_real:
                continue
            A = np.empty((dim, dim))
            B = np.empty((dim, dim))
            if dim == 3:  # the 3 x 3 scratch, read in 3D only (A stands in elsewhere)
                inv, F, C = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
            else:
                inv = F = C = A
            out[i] = stretch_row(p, order, offsets, indices, x, x0, body, h, A, B, inv, F,
                                 C, dim)
        return out

    return stretches


@nb.njit(cache=True)
def mirrored_rows(x, x0, body, h, src, wall, points, normals, kinds):
    """The rows of a list with ghosts (:func:`principal_stretches`' ``x``, ``x0``, ``body``,
    ``h``) from the real particles' and the ghosts' sources and planes: a symmetry plane's
    ghost is its source mirrored across the plane, now and at t = 0 (in order: a ghost may
    mirror an earlier ghost), and belongs to its source's body, so that a half model's
    neighbourhoods are the whole model's; a rigid wall's ghost belongs to no body (-1)."""
    n, dim = x.shape
    rows = n + src.shape[0]
    xe, x0e = np.empty((rows, dim)), np.empty((rows, dim))
    be, he = np.empty(rows, np.int64), np.empty(rows)
    xe[:n], x0e[:n], be[:n], he[:n] = x, x0, body, h
    for k in range(src.shape[0]):
        mirror_row(k, n, xe, x0e, be, he, src, wall, points, normals, kinds)
    return xe, x0e, be, he


@nb.njit(inline="always", cache=True)
def mirror_row(k, n, xe, x0e, be, he, src, wall, points, normals, kinds):
    """Ghost ``k``'s row of :func:`mirrored_rows` (row ``n + k``), from its source's row
    (a particle's, or an earlier ghost's): one ghost of the CPU's loop, and of the device's
    (:mod:`impactsph.gpu_step`, stage by stage)."""
    dim = xe.shape[1]
    i, w, g = src[k], wall[k], n + k
    d = 0.0
    d0 = 0.0
    for a in range(dim):
        d += (xe[i, a] - points[w, a]) * normals[w, a]
        d0 += (x0e[i, a] - points[w, a]) * normals[w, a]
    for a in range(dim):
        xe[g, a] = xe[i, a] - 2.0 * d * normals[w, a]
        x0e[g, a] = x0e[i, a] - 2.0 * d0 * normals[w, a]
    be[g] = be[i] if kinds[w] == SYMMETRY else -1
    he[g] = he[i]


def stretched_smoothing_length(neighbours, x: np.ndarray, x0: np.ndarray, body: np.ndarray,
                               h0: np.ndarray, max_stretch: float, h: np.ndarray,
                               ghosts: tuple | None = None) -> np.ndarray:
    """(ST-1) for the real particles (``x``, ``x0``, ``body``, ``h0``, ``h`` and the result
    have a row each).  ``ghosts``: ``(src, wall, points, normals, kinds)`` of the ghost rows
    of ``neighbours`` (:class:`impactsph.boundaries.Walls`), None where it has none."""
    n = x0.shape[0]
    if ghosts is None:
        ghosts = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, x.shape[1])),
                  np.zeros((0, x.shape[1])), np.zeros(0, np.int8))
    rows = mirrored_rows(np.ascontiguousarray(x), np.ascontiguousarray(x0),
                         body.astype(np.int64), np.ascontiguousarray(h), *ghosts)
    stretch = principal_stretches(neighbours.order, neighbours.offsets, neighbours.indices,
                                  *rows, n)
    factor = np.where(stretch > 0.0, np.clip(stretch, 1.0, max_stretch), 1.0)
    return h0 * factor
