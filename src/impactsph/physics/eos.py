"""Equations of state (paper eqs 6-12, NOTES 5).  Pressure is positive in compression.

Linear (eq 6)::

    P = K (rho / rho0 - 1)

Mie-Gruneisen (eqs 7-12, with the tension branch of eq 8 corrected to ``a0 eta``)::

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

LINEAR = 0
MIE_GRUNEISEN = 1


@nb.njit(inline="always", cache=True)
def linear_pressure(rho: float, rho0: float, bulk_modulus: float) -> float:
    """Eq 6: ``P = K (rho/rho0 - 1)``."""
    return bulk_modulus * (rho / rho0 - 1.0)


@nb.njit(inline="always", cache=True)
def mie_gruneisen_coefficients(rho0: float, sound_speed: float, slope: float):
    """Eqs 10-12: ``(a0, b0, c0)`` of the Hugoniot fit."""
    a0 = rho0 * sound_speed * sound_speed
    b0 = a0 * (1.0 + 2.0 * (slope - 1.0))
    c0 = a0 * (2.0 * (slope - 1.0) + 3.0 * (slope - 1.0) ** 2)
    return a0, b0, c0


@nb.njit(inline="always", cache=True)
def mie_gruneisen_pressure(
    rho: float, e: float, rho0: float, a0: float, b0: float, c0: float, gamma: float
) -> float:
    """Eqs 7-9: ``P = (1 - Gamma eta/2) P_H + Gamma rho e``."""
    eta = rho / rho0 - 1.0
    if eta > 0.0:
        p_h = eta * (a0 + eta * (b0 + eta * c0))
    else:
        p_h = a0 * eta
    return (1.0 - 0.5 * gamma * eta) * p_h + gamma * rho * e


def pressure(
    density: np.ndarray,
    specific_energy: np.ndarray,
    rho0: float,
    *,
    bulk_modulus: float | None = None,
    sound_speed: float | None = None,
    slope: float | None = None,
    gamma: float | None = None,
) -> np.ndarray:
    """Vectorised pressure for analysis and tests: linear if ``bulk_modulus`` is given,
    Mie-Gruneisen if ``sound_speed``, ``slope`` and ``gamma`` are."""
    density = np.asarray(density, dtype=np.float64)
    if bulk_modulus is not None:
        return bulk_modulus * (density / rho0 - 1.0)
    a0, b0, c0 = mie_gruneisen_coefficients(rho0, sound_speed, slope)
    energy = np.broadcast_to(np.asarray(specific_energy, dtype=np.float64), density.shape)
    return np.array(
        [mie_gruneisen_pressure(r, e, rho0, a0, b0, c0, gamma)
         for r, e in zip(density.ravel(), energy.ravel(), strict=True)]
    ).reshape(density.shape)
