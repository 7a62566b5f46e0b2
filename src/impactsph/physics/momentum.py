"""Momentum equation (paper eq 27; docs/modelling.md), Cauchy stress, tension positive.

With ``sigma = -P I + S`` and ``A_i = sigma_i / rho_i^2``::

    dv_i/dt = sum_j m_j (A_i + A_j - Pi_ij I) . grad W_ij                   (eq 27)

The stress part and the artificial-viscosity part are accumulated separately so that the
viscosity can be corrected (AC) and its power booked in the energy budget.  The pair terms
are antisymmetric in ``i, j``, so linear momentum is conserved to round-off.

The pair loop (:mod:`.rates`) applies the stress term regrouped, ``A_i . sum_j m_j grad W_ij +
sum_j m_j A_j . grad W_ij``, equal in exact arithmetic; ``tests/test_rates_reference.py``
checks it against :func:`stress_acceleration_pair` summed pair by pair.
"""

from __future__ import annotations

import numba as nb


@nb.njit(inline="always", cache=True)
def stress_acceleration_pair(m_j: float, A_i, A_j, gradw, a: int, dim: int) -> float:
    """Component ``a`` of ``m_j (A_i + A_j) . grad W_ij``."""
    s = 0.0
    for b in range(dim):
        s += (A_i[a, b] + A_j[a, b]) * gradw[b]
    return m_j * s


@nb.njit(inline="always", cache=True)
def viscous_acceleration_pair(m_j: float, pi_ij: float, gradw_a: float) -> float:
    """Component of ``-m_j Pi_ij grad W_ij`` (the AV term of eq 27)."""
    return -m_j * pi_ij * gradw_a
