"""Deviatoric stress rate with the Jaumann co-rotational derivative (eqs 14-16).

From the SPH velocity gradient ``L^ab = dv^a/dx^b`` (see :mod:`.rates`)::

    eps_dot = (L + L^T) / 2            strain rate (eq 15)
    omega   = (L - L^T) / 2            spin (eq 16)
    dS/dt   = 2 mu (eps_dot - tr(eps_dot)/3 I) + omega.S - S.omega

The factor 2 is missing from the printed eqs 13 and 25 (docs/modelling.md).  ``L`` has the
dimension of the problem; ``S`` is always 3x3, and the components of ``L`` out of the plane
are zero (plane strain in 2D), so ``dS_zz/dt = -2 mu tr(eps_dot)/3`` keeps ``S`` traceless.
"""

from __future__ import annotations

import numba as nb


@nb.njit(inline="always", cache=True)
def jaumann_stress_rate_nd(L, S, shear_modulus: float, dS, dim: int) -> None:
    """Write ``dS/dt`` for velocity gradient ``L`` (``dim x dim``) and deviator ``S`` into
    ``dS``.  A caller with ``dim`` a compile-time constant (a generated pass's ``DIM``) gets
    the loops unrolled and the tests on ``dim`` folded away: the same arithmetic in the same
    order (the 2D pair pass took 15% less time for it in the test machine's slow spells, and
    no measurable difference otherwise; benchmarks/README.md)."""
    trace = 0.0
    for a in range(dim):
        trace += L[a, a]
    for a in range(3):
        for b in range(3):
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
            dS[a, b] = 2.0 * shear_modulus * eps + rot


@nb.njit(inline="always", cache=True)
def jaumann_stress_rate(L, S, shear_modulus: float, dS) -> None:
    """Write ``dS/dt`` for velocity gradient ``L`` (dim x dim) and deviator ``S`` into ``dS``
    (:func:`jaumann_stress_rate_nd` with ``dim`` read from ``L``'s shape)."""
    jaumann_stress_rate_nd(L, S, shear_modulus, dS, L.shape[0])
