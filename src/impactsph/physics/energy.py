"""Energy equation (paper eq 28; docs/modelling.md): specific internal energy ``e`` (J/kg).

::

    de_i/dt = -A_i : sum_j m_j v_ij (x) grad W_ij + 1/2 sum_j m_j Pi_ij v_ij . grad W_ij

with ``A_i = sigma_i / rho_i^2``.  These are the work terms that match eq 27 pair by pair, so
``sum_i m_i (v_i . dv_i/dt + de_i/dt) = 0``: total energy is conserved by the semi-discrete
equations.  The viscous part is the dissipation of the artificial viscosity (non-negative).

The pair loop (:mod:`.rates`) applies the stress work regrouped,
``-A_i : sum_j m_j v_ij (x) grad W_ij``, equal in exact arithmetic;
``tests/test_rates_reference.py`` checks it against :func:`stress_work_pair`.
"""

from __future__ import annotations

import numba as nb


@nb.njit(inline="always", cache=True)
def stress_work_pair(m_j: float, A_i, v_ij, gradw, dim: int) -> float:
    """``-m_j A_i : (v_ij (x) grad W_ij)``."""
    s = 0.0
    for a in range(dim):
        for b in range(dim):
            s += A_i[a, b] * v_ij[a] * gradw[b]
    return -m_j * s


@nb.njit(inline="always", cache=True)
def viscous_heating_pair(m_j: float, pi_ij: float, v_dot_gradw: float) -> float:
    """``1/2 m_j Pi_ij v_ij . grad W_ij`` (the AV term of eq 28)."""
    return 0.5 * m_j * pi_ij * v_dot_gradw
