"""Contact between bodies: compression only, frictionless (docs/modelling.md, "Contact
between bodies").

Particles of different bodies interact through their pressures alone.  With
``s_ij = P_i/rho_i^2 + P_j/rho_j^2`` the pair is *in contact* while ``s_ij > 0`` (it pushes)
or while it approaches (``v_ij . grad W_ij > 0``: the gap is closing); otherwise the interface
is open and the pair contributes nothing.  In contact::

    drho_i/dt += rho_i V_j v_ij . grad W_ij                    (the other body compresses i)
    dv_i/dt   += -m_j max(s_ij, 0) grad W_ij                   (repulsion only)
    de_i/dt   +=  m_j (P_i/rho_i^2) [s_ij > 0] v_ij . grad W_ij

The force is antisymmetric (momentum exact); the energy terms of ``i`` and ``j`` add up to the
work of the pair force (total energy exact), and each particle's share ``P_i/rho_i^2`` keeps
its internal energy consistent with its density change.  The interface carries no tension, so
the bars separate when the reflected wave arrives, and no shear.  Artificial viscosity acts
across bodies as within one, and only on approaching pairs, so it too can only push.
"""

from __future__ import annotations

import numba as nb


@nb.njit(inline="always", cache=True)
def in_contact(s_ij: float, v_dot_gradw: float) -> bool:
    """Whether a pair of particles of different bodies interacts."""
    return s_ij > 0.0 or v_dot_gradw > 0.0


@nb.njit(inline="always", cache=True)
def contact_acceleration_pair(m_j: float, s_ij: float, gradw_a: float) -> float:
    """Component of ``-m_j max(s_ij, 0) grad W_ij``."""
    return -m_j * max(s_ij, 0.0) * gradw_a


@nb.njit(inline="always", cache=True)
def contact_work_pair(m_j: float, p_over_rho2_i: float, s_ij: float, v_dot_gradw: float) -> float:
    """``m_j (P_i/rho_i^2) v_ij . grad W_ij`` while the pair pushes, else 0."""
    if s_ij <= 0.0:
        return 0.0
    return m_j * p_over_rho2_i * v_dot_gradw
