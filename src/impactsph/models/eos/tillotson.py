"""Tillotson equation of state (Tillotson 1962, General Atomics report GA-3216; as written in
Melosh 1989, *Impact Cratering*, Appendix II, and Benz & Asphaug 1999, Icarus 142, 5-20;
the form of miluphcuda and Spheral)::

    eta = rho / rho0,   mu = eta - 1,   omega = e / (E0 eta^2) + 1

    compressed or cold expanded (rho >= rho0, or e < E_iv):
        P_c = (a + b / omega) rho e + A mu + B mu^2
    hot expanded (rho < rho0 and e > E_cv):
        P_e = a rho e + (b rho e / omega + A mu exp(-beta (rho0/rho - 1)))
                        exp(-alpha (rho0/rho - 1)^2)
    in between (rho < rho0 and E_iv <= e <= E_cv), linear in e:
        P   = ((e - E_iv) P_e + (E_cv - e) P_c) / (E_cv - E_iv)

``rho0`` is the material's ``density``; ``a``, ``b``, ``alpha``, ``beta`` are dimensionless,
``A`` and ``B`` in Pa, ``E0``, ``E_iv`` (incipient vaporisation) and ``E_cv`` (complete
vaporisation) specific energies in J/kg, like ``e``.

Continuity: P is continuous everywhere it is defined (``omega != 0``).  At ``rho = rho0``
``mu = 0`` and both exponentials are 1, so ``P_e = P_c``; at ``e = E_iv`` the interpolation is
``P_c`` and at ``e = E_cv`` it is ``P_e``.  The derivatives are not continuous: ``dP/de`` jumps
at ``e = E_iv`` and ``e = E_cv`` (rho < rho0), ``dP/drho`` at ``rho = rho0`` for ``e > E_iv``.
``omega`` vanishes at ``e = -E0 eta^2``: a negative specific energy that large is outside the
model (no guard, as in the sources).

Bulk modulus: ``A`` is the Tillotson tangent bulk modulus at ``rho0``, ``e = 0``
(``dP/dmu = A``).  The kernels' ``bulk_modulus`` column, which sets the time step's and the
viscosity's wave speed (``K + 4/3 mu``, ``time.wave_speed = "p_wave"``) and the walls'
penalty, is the material's ``K = E / (3 (1 - 2 nu))`` as for every equation of state; the
pressure here does not use it.  Choose ``youngs_modulus`` and ``poisson_ratio`` so that
``K`` is ``A`` (``E = 3 A (1 - 2 nu)``), so the time step follows the EOS's sound speed.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from pydantic import Field, ValidationInfo, field_validator

from ..registry import EOS, EquationOfState, Parameters
from ..types import PositiveFloat


class TillotsonParameters(Parameters):
    """``[materials.NAME.tillotson]``: Tillotson's ten constants less ``rho0`` (the material's
    ``density``); every one required."""

    a: PositiveFloat = Field(description="Tillotson a (dimensionless)")
    b: PositiveFloat = Field(description="Tillotson b (dimensionless)")
    A: PositiveFloat = Field(description="Tillotson A, bulk modulus at rho0 (Pa)")
    B: PositiveFloat = Field(description="Tillotson B, nonlinear compression term (Pa)")
    E0: PositiveFloat = Field(description="Tillotson E0 (J/kg)")
    E_iv: PositiveFloat = Field(description="specific energy of incipient vaporisation (J/kg)")
    E_cv: PositiveFloat = Field(description="specific energy of complete vaporisation (J/kg), "
                                            "> E_iv")
    alpha: PositiveFloat = Field(description="Tillotson alpha (dimensionless)")
    beta: PositiveFloat = Field(description="Tillotson beta (dimensionless)")

    @field_validator("E_cv")
    @classmethod
    def _above_incipient(cls, value: float, info: ValidationInfo) -> float:
        e_iv = info.data.get("E_iv")
        if e_iv is not None and not value > e_iv:
            raise ValueError(f"must be greater than E_iv = {e_iv}")
        return value


@nb.njit(inline="always", cache=True)
def tillotson_pressure(rho: float, e: float, rho0: float, a: float, b: float, A: float,
                       B: float, E0: float, E_iv: float, E_cv: float, alpha: float,
                       beta: float) -> float:
    """``P(rho, e)`` of the module docstring."""
    eta = rho / rho0
    mu = eta - 1.0
    omega = e / (E0 * eta * eta) + 1.0
    p_c = (a + b / omega) * rho * e + A * mu + B * mu * mu
    if rho >= rho0 or e < E_iv:
        return p_c
    z = rho0 / rho - 1.0
    p_e = a * rho * e + (b * rho * e / omega + A * mu * math.exp(-beta * z)) * math.exp(
        -alpha * z * z)
    if e > E_cv:
        return p_e
    return ((e - E_iv) * p_e + (E_cv - e) * p_c) / (E_cv - E_iv)


@nb.njit(inline="always", cache=True)
def pressure(rho: float, e: float, rho0: float, bulk_modulus: float, params) -> float:
    """The registered form: ``params`` are the table columns
    ``(a, b, A, B, E0, E_iv, E_cv, alpha, beta)``; ``bulk_modulus`` is not used."""
    return tillotson_pressure(rho, e, rho0, params[0], params[1], params[2], params[3],
                              params[4], params[5], params[6], params[7], params[8])


COLUMNS = ("a", "b", "A", "B", "E0", "E_iv", "E_cv", "alpha", "beta")


def coefficients(p: TillotsonParameters, constants) -> tuple[float, ...]:
    """Table columns: the parameters as given (``rho0`` is the table's density column; the
    table's bulk modulus stays the material's ``K``, see the module docstring)."""
    return tuple(float(getattr(p, name)) for name in COLUMNS)


def pressure_of(density: np.ndarray, specific_energy: np.ndarray, rho0: float,
                **parameters: float) -> np.ndarray:
    """Vectorised Tillotson pressure, for analysis and tests (``parameters`` by name)."""
    values = tuple(float(parameters[name]) for name in COLUMNS)
    density = np.asarray(density, dtype=np.float64)
    energy = np.broadcast_to(np.asarray(specific_energy, dtype=np.float64), density.shape)
    return np.array([tillotson_pressure(r, e, rho0, *values)
                     for r, e in zip(density.ravel(), energy.ravel(), strict=True)]
                    ).reshape(density.shape)


TILLOTSON = EOS.register(EquationOfState(
    name="tillotson", pressure=pressure, parameters=TillotsonParameters, columns=COLUMNS,
    coefficients=coefficients,
    source="Tillotson (1962) GA-3216; Melosh (1989) App. II; Benz & Asphaug (1999)",
    description="Tillotson: compressed/cold P_c, hot expanded P_e, linear in e between"))
