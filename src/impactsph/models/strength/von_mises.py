"""Von Mises perfect plasticity by radial return (paper eqs 17-18; docs/modelling.md).

The deviatoric stress ``S`` is stored as a full 3x3 tensor: in plane strain its out-of-plane
component ``S_zz = -(S_xx + S_yy)`` is carried and enters the norm.  The von Mises equivalent
stress is ``sigma_eq = sqrt(3/2 S:S)``; where it exceeds the yield stress ``sigma_y`` the
deviator is scaled back onto the yield surface::

    S <- f S,    f = min(sigma_y / sigma_eq, 1)

The specific plastic work of one return is the drop in stored deviatoric elastic energy,
``(S_trial:S_trial - S:S) / (4 mu rho)`` (J/kg).  Registered as ``model = "elastic_plastic"``
with the flat material field ``yield_stress`` (Pa).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from pydantic import Field

from ..registry import STRENGTH, Parameters, StrengthModel
from ..types import PositiveFloat


class VonMisesParameters(Parameters):
    """The yield stress, a field of the material table."""

    yield_stress: PositiveFloat = Field(description="von Mises yield stress sigma_y (Pa)")


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
    """Equivalent stress ``sqrt(3/2 S:S)`` of a deviator."""
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


@nb.njit(inline="always", cache=True)
def return_map(S, rho: float, shear_modulus: float, params, state) -> float:
    """The registered form: radial return to ``sigma_y = params[0]``; returns the specific
    plastic work ``S_trial:S_trial (1 - f^2) / (4 mu rho)`` (J/kg)."""
    before = double_contraction(S)
    f = radial_return(S, params[0])
    if f < 1.0:
        return before * (1.0 - f * f) / (4.0 * shear_modulus * rho)
    return 0.0


def von_mises_stress(deviatoric_stress: np.ndarray) -> np.ndarray:
    """Vectorised ``sqrt(3/2 S:S)`` for an array of 3x3 deviators, shape (..., 3, 3)."""
    S = np.asarray(deviatoric_stress)
    return np.sqrt(1.5 * np.einsum("...ab,...ab->...", S, S))


VON_MISES = STRENGTH.register(StrengthModel(
    name="elastic_plastic", return_map=return_map, parameters=VonMisesParameters, flat=True,
    columns=("yield_stress",), coefficients=lambda p, constants: (p.yield_stress,),
    source="Shaw & Reid (2009) eqs 17-18",
    description="von Mises perfect plasticity (radial return)"))
