"""Monaghan artificial viscosity (paper eqs 29-30), registered as ``scheme = "av"``.

For an approaching pair (``v_ij . r_ij < 0``)::

    mu_ij = h_ij (v_ij . r_ij) / (r_ij^2 + eps h_ij^2)
    Pi_ij = (-alpha1 c_ij mu_ij + alpha2 mu_ij^2) / rho_ij

and ``Pi_ij = 0`` otherwise; ``c_ij``, ``h_ij``, ``rho_ij`` are pair means.  ``Pi_ij`` has
the units of ``sigma / rho^2`` (m^5 kg^-1 s^-2) and enters the momentum equation as
``- sum_j m_j Pi_ij grad W_ij`` (eq 27) and the energy equation as
``1/2 sum_j m_j Pi_ij v_ij . grad W_ij`` (eq 28).  The paper's sets are AV1 = (1, 1),
AV2 = (1, 2), AV3 = (2.5, 2.5).
"""

from __future__ import annotations

import numba as nb
from pydantic import Field

from ..registry import VISCOSITY, Parameters, ViscosityScheme
from ..types import NonNegativeFloat, PositiveFloat


class MonaghanParameters(Parameters):
    """The ``[viscosity]`` fields of Monaghan's viscosity."""

    alpha1: NonNegativeFloat = Field(1.0, description="linear coefficient alpha1 of eq 29")
    alpha2: NonNegativeFloat = Field(1.0, description="quadratic coefficient alpha2 of eq 29")
    epsilon: PositiveFloat = Field(0.01, description="epsilon of eq 30")


@nb.njit(inline="always", cache=True)
def monaghan_viscosity(vr: float, r2: float, h_ij: float, c_ij: float, rho_ij: float,
                       alpha1: float, alpha2: float, epsilon: float) -> float:
    """``Pi_ij`` of eq 29 for a pair with ``vr = v_ij . r_ij`` and ``r2 = |r_ij|^2``."""
    # min(vr, 0): zero for a receding pair, without a branch (whether a pair approaches is
    # close to random in a noisy flow, and a mispredicted branch costs more than the division)
    mu_ij = h_ij * min(vr, 0.0) / (r2 + epsilon * h_ij * h_ij)
    return (-alpha1 * c_ij * mu_ij + alpha2 * mu_ij * mu_ij) / rho_ij


@nb.njit(inline="always", cache=True)
def pair_viscosity(vr: float, r2: float, h_ij: float, c_ij: float, rho_ij: float,
                   params) -> float:
    """The registered form: ``params = (alpha1, alpha2, epsilon, unused)``."""
    return monaghan_viscosity(vr, r2, h_ij, c_ij, rho_ij, params[0], params[1], params[2])


MONAGHAN = VISCOSITY.register(ViscosityScheme(
    name="av", pair_viscosity=pair_viscosity, parameters=MonaghanParameters,
    pair_parameters=lambda v: (float(v.alpha1), float(v.alpha2), float(v.epsilon), 0.0),
    source="Shaw & Reid (2009) eqs 29-30", description="Monaghan artificial viscosity"))
