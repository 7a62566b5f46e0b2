"""Mie-Gruneisen equation of state (paper eqs 7-12, the tension branch of eq 8 corrected to
``a0 eta``; docs/modelling.md)::

    eta = rho / rho0 - 1
    P_H = a0 eta + b0 eta^2 + c0 eta^3   (eta > 0),    P_H = a0 eta   (eta <= 0)
    P   = (1 - Gamma eta / 2) P_H + Gamma rho e
    a0 = rho0 C^2,  b0 = a0 (1 + 2 (S - 1)),  c0 = a0 (2 (S - 1) + 3 (S - 1)^2)

``C`` is the bulk sound speed (m/s), ``S`` the slope of the shock-velocity/particle-velocity
fit and ``Gamma`` the Gruneisen parameter; ``e`` is the specific internal energy (J/kg).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from pydantic import Field

from ..registry import EOS, EquationOfState, Parameters
from ..types import NonNegativeFloat, PositiveFloat


class MieGruneisenParameters(Parameters):
    """``[materials.NAME.mie_gruneisen]``: the Hugoniot fit and the Gruneisen parameter."""

    sound_speed: PositiveFloat = Field(description="bulk sound speed C of eq 10 (m/s)")
    slope: NonNegativeFloat = Field(description="Hugoniot slope S of eqs 11-12")
    gamma: NonNegativeFloat = Field(description="Gruneisen parameter Gamma of eq 7")


@nb.njit(inline="always", cache=True)
def hugoniot_coefficients(rho0: float, sound_speed: float, slope: float):
    """Eqs 10-12: ``(a0, b0, c0)`` of the Hugoniot fit."""
    a0 = rho0 * sound_speed * sound_speed
    b0 = a0 * (1.0 + 2.0 * (slope - 1.0))
    c0 = a0 * (2.0 * (slope - 1.0) + 3.0 * (slope - 1.0) ** 2)
    return a0, b0, c0


@nb.njit(inline="always", cache=True)
def mie_gruneisen_pressure(rho: float, e: float, rho0: float, a0: float, b0: float, c0: float,
                           gamma: float) -> float:
    """Eqs 7-9: ``P = (1 - Gamma eta/2) P_H + Gamma rho e``."""
    eta = rho / rho0 - 1.0
    if eta > 0.0:
        p_h = eta * (a0 + eta * (b0 + eta * c0))
    else:
        p_h = a0 * eta
    return (1.0 - 0.5 * gamma * eta) * p_h + gamma * rho * e


@nb.njit(inline="always", cache=True)
def pressure(rho: float, e: float, rho0: float, bulk_modulus: float, params) -> float:
    """The registered form: ``params = (a0, b0, c0, Gamma)`` (the table columns)."""
    return mie_gruneisen_pressure(rho, e, rho0, params[0], params[1], params[2], params[3])


def coefficients(p: MieGruneisenParameters, constants) -> tuple[float, ...]:
    """Table columns ``(a0, b0, c0, Gamma)`` from ``C``, ``S``, ``Gamma`` and ``rho0``."""
    a0, b0, c0 = hugoniot_coefficients(constants.density, p.sound_speed, p.slope)
    return a0, b0, c0, p.gamma


def pressure_of(density: np.ndarray, specific_energy: np.ndarray, rho0: float,
                sound_speed: float, slope: float, gamma: float) -> np.ndarray:
    """Vectorised Mie-Gruneisen pressure, for analysis and tests."""
    density = np.asarray(density, dtype=np.float64)
    a0, b0, c0 = hugoniot_coefficients(rho0, sound_speed, slope)
    energy = np.broadcast_to(np.asarray(specific_energy, dtype=np.float64), density.shape)
    return np.array([mie_gruneisen_pressure(r, e, rho0, a0, b0, c0, gamma)
                     for r, e in zip(density.ravel(), energy.ravel(), strict=True)]
                    ).reshape(density.shape)


MIE_GRUNEISEN = EOS.register(EquationOfState(
    name="mie_gruneisen", pressure=pressure, parameters=MieGruneisenParameters,
    columns=("a0", "b0", "c0", "gamma"), coefficients=coefficients,
    source="Shaw & Reid (2009) eqs 7-12",
    description="P = (1 - Gamma eta/2) P_H(eta) + Gamma rho e"))
