"""Continuity equation and velocity gradient (paper eqs 22, 15-16).

Pair contributions, with ``V_j = m_j / rho_j`` and ``grad W_ij`` taken at ``x_i``::

    drho_i/dt = rho_i sum_j V_j v_ij . grad W_ij                    (eq 22)
    L_i^ab    = -sum_j V_j v_ij^a dW_ij/dx^b                        (velocity gradient)

The continuity sum runs over all neighbours, those of other bodies included, so that bodies in
contact compress each other; the velocity gradient (and so the deviatoric stress) uses
neighbours of the same body only, which makes contact frictionless (see :mod:`.contact`).
"""

from __future__ import annotations

import numba as nb


@nb.njit(inline="always", cache=True)
def continuity_pair(rho_i: float, volume_j: float, v_dot_gradw: float) -> float:
    """Pair term of eq 22: ``rho_i V_j v_ij . grad W_ij``."""
    return rho_i * volume_j * v_dot_gradw


@nb.njit(inline="always", cache=True)
def velocity_gradient_pair(volume_j: float, v_ij_a: float, gradw_b: float) -> float:
    """Pair term of ``L^ab``: ``-V_j v_ij^a dW_ij/dx^b``."""
    return -volume_j * v_ij_a * gradw_b
