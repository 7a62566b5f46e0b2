"""Deviatoric stress rate with the Jaumann co-rotational derivative (eqs 14-16).

From the SPH velocity gradient ``L^ab = dv^a/dx^b`` (see :mod:`.rates`)::

    eps_dot = (L + L^T) / 2            strain rate (eq 15)
    omega   = (L - L^T) / 2            spin (eq 16)
    dS/dt   = 2 mu (eps_dot - tr(eps_dot)/3 I) + omega.S - S.omega

The factor 2 is missing from the printed eqs 13 and 25 (docs/modelling.md).  ``L`` has the
dimension of the problem; ``S`` is always 3x3, and the components of ``L`` out of the plane
are zero (plane strain in 2D), so ``dS_zz/dt = -2 mu tr(eps_dot)/3`` keeps ``S`` traceless.

The rate is symmetric, and is written as its six components ``(xx, xy, xz, yy, yz, zz)`` (the
upper triangle row by row, :data:`UPPER`): the solver's rate buffer and the integrator's
copy of ``S`` at the step's start hold six numbers a particle, not nine (48 bytes a particle
less), and the integrator writes ``S_ba = S_ab``, so the deviator is exactly symmetric.  In
1D and 2D the nine-component rate was already symmetric to the bit (its ``xy`` and ``yx``
terms are the same products in the same order), so those runs are unchanged; in 3D the
``xy`` and ``yx`` components were the same sums in different orders and differed at
round-off, so 3D results move at round-off (benchmarks/README.md, "The stress rate's six
components").
"""

from __future__ import annotations

import numba as nb
import numpy as np

#: ``UPPER[a][b]``: where component ``(a, b)`` of a symmetric 3x3 tensor stored as its six
#: components (the upper triangle, row by row) is
UPPER = ((0, 1, 2), (1, 3, 4), (2, 4, 5))
#: the six components' positions in a 3x3 tensor's nine, row by row
UPPER_FLAT = (0, 1, 2, 4, 5, 8)


def symmetric_upper(tensor: np.ndarray) -> np.ndarray:
    """The six components ``(xx, xy, xz, yy, yz, zz)`` of ``(..., 3, 3)`` tensors (the upper
    triangle; a symmetric tensor's, as :func:`jaumann_stress_rate` writes them)."""
    tensor = np.asarray(tensor)
    return tensor.reshape(*tensor.shape[:-2], 9)[..., list(UPPER_FLAT)]


def symmetric_full(components: np.ndarray) -> np.ndarray:
    """The ``(..., 3, 3)`` symmetric tensors of six components ``(xx, xy, xz, yy, yz, zz)``
    (the inverse of :func:`symmetric_upper` for a symmetric tensor)."""
    components = np.asarray(components)
    return components[..., np.array(UPPER)]


@nb.njit(inline="always", cache=True)
def store_upper(S, out, i: int) -> None:
    """``out[i]``: the six components of ``S[i]`` (3x3; its upper triangle, :data:`UPPER`):
    the integrator's start copy of the deviator, on the CPU (``integrate.keep_upper``) and on
    the device (``gpu_step``'s ``start_kernel``)."""
    for a in range(3):
        for b in range(a, 3):
            out[i, UPPER[a][b]] = S[i, a, b]


@nb.njit(inline="always", cache=True)
def jaumann_stress_rate_nd(L, S, shear_modulus: float, dS, dim: int) -> None:
    """Write ``dS/dt`` for velocity gradient ``L`` (``dim x dim``) and deviator ``S``
    (3x3) into ``dS``: its six components ``(xx, xy, xz, yy, yz, zz)`` (:data:`UPPER`).  A
    caller with ``dim`` a compile-time constant (a generated pass's ``DIM``) gets the loops
    unrolled and the tests on ``dim`` folded away: the same arithmetic in the same order (the
    2D pair pass took 15% less time for it in the test machine's slow spells, and no
    measurable difference otherwise; benchmarks/README.md)."""
    trace = 0.0
    for a in range(dim):
        trace += L[a, a]
    for a in range(3):
        for b in range(a, 3):
            eps = 0.0
            if a < dim and b < dim:
                eps = 0.5 * (L[a, b] + L[b, a])
            if a == b:
                eps -= trace / 3.0
            # (omega.S - S.omega)_ab = sum_c omega_ac S_cb - S_ac omega_cb
            rot = 0.0
            for c in range(dim):
                if a < dim:
                    rot += 0.5 * (L[a, c] - L[c, a]) * S[c, b]
                if b < dim:
                    rot -= S[a, c] * 0.5 * (L[c, b] - L[b, c])
            dS[UPPER[a][b]] = 2.0 * shear_modulus * eps + rot


@nb.njit(inline="always", cache=True)
def jaumann_stress_rate(L, S, shear_modulus: float, dS) -> None:
    """Write ``dS/dt`` for velocity gradient ``L`` (dim x dim) and deviator ``S`` into ``dS``,
    its six components (:func:`jaumann_stress_rate_nd` with ``dim`` read from ``L``'s shape;
    :func:`symmetric_full` gives the 3x3 tensor)."""
    jaumann_stress_rate_nd(L, S, shear_modulus, dS, L.shape[0])
