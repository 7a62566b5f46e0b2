"""Von Mises perfect plasticity by radial return (paper eqs 17-18, NOTES 3-4).

The deviatoric stress ``S`` is stored as a full 3x3 tensor: in plane strain its out-of-plane
component ``S_zz = -(S_xx + S_yy)`` is carried and enters the norm.  The von Mises equivalent
stress is ``sigma_eq = sqrt(3/2 S:S)``; where it exceeds the yield stress ``sigma_y`` the
deviator is scaled back onto the yield surface::

    S <- f S,    f = min(sigma_y / sigma_eq, 1)

The specific plastic work of one return is the drop in stored deviatoric elastic energy,
``(S_trial:S_trial - S:S) / (4 mu rho)`` (J/kg).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(inline="always", cache=True)
def double_contraction(S) -> float:
    """``S:S`` of a 3x3 tensor."""
    s = 0.0
    for a in range(3):
        for b in range(3):
            s += S[a, b] * S[a, b]
    return s


@nb.njit(inline="always", cache=True)
def von_mises(S) -> float:
    """Equivalent stress ``sqrt(3/2 S:S)`` of a deviator (NOTES 4)."""
    return math.sqrt(1.5 * double_contraction(S))


@nb.njit(inline="always", cache=True)
def radial_return(S, yield_stress: float) -> float:
    """Scale ``S`` in place onto the yield surface (eqs 17-18); return the factor ``f``."""
    seq = von_mises(S)
    if seq <= yield_stress:
        return 1.0
    f = yield_stress / seq
    for a in range(3):
        for b in range(3):
            S[a, b] *= f
    return f


def von_mises_stress(deviatoric_stress: np.ndarray) -> np.ndarray:
    """Vectorised ``sqrt(3/2 S:S)`` for an array of 3x3 deviators, shape (..., 3, 3)."""
    S = np.asarray(deviatoric_stress)
    return np.sqrt(1.5 * np.einsum("...ab,...ab->...", S, S))
