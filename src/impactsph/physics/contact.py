"""Contact between bodies: compression only, with Coulomb friction where a case asks for it
(docs/modelling.md, "Contact between bodies").

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
the bars separate when the reflected wave arrives, and no shear but friction's.  Artificial
viscosity acts across bodies as within one, and only on approaching pairs, so it too can only
push.

Friction (``[contact] friction = mu``): a pushing pair (``s_ij > 0``) whose particles slide
past each other with ``u_t``, the part of ``v_ij`` across the line of centres, is slowed by
Coulomb's law on the pair's own normal force (the push's magnitude
``f_ij = m_j s_ij |grad W_ij|`` per unit mass of ``i``)::

    dv_i/dt += -mu f_ij u_t / sqrt(|u_t|^2 + v_r^2)
    de_i/dt += 1/2 mu f_ij |u_t|^2 / sqrt(|u_t|^2 + v_r^2)

with ``v_r = FRICTION_REGULARISATION (c_i + c_j) / 2`` (a smooth stick below it).  The force is
antisymmetric, and its power, always dissipative, is shared equally by the pair as heat: the
total energy is kept.
"""

from __future__ import annotations

import math

import numba as nb

#: the regularising speed of Coulomb friction (walls and bodies), in units of the material's
#: wave speed: a particle sliding slower than this feels a friction falling to zero with its
#: speed (a smooth stick), so that the friction cannot reverse a slow slide within a step
FRICTION_REGULARISATION = 1e-6


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


@nb.njit(inline="always", cache=True)
def friction_factor(mu: float, push: float, slip2: float, v_reg: float) -> float:
    """``mu f / sqrt(|u_t|^2 + v_r^2)``: the friction acceleration per unit of sliding
    velocity for the push ``f`` (per unit mass) and the squared slip ``|u_t|^2``."""
    return mu * push / math.sqrt(slip2 + v_reg * v_reg)
