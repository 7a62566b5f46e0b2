"""Isotropic hardening and Johnson-Cook strength: von Mises plasticity whose yield stress
grows with the equivalent plastic strain, the plastic strain rate and falls with temperature.

Flow stress (Johnson & Cook 1983, eq 1)::

    sigma_y(eps_p, rate, T) = (A + B eps_p^n) (1 + C ln max(rate / rate0, 1)) (1 - T*^m)
    T* = (T - T_r) / (T_melt - T_r), clipped to [0, 1]

Three models share it: ``linear_hardening`` (``n = 1``, ``C = 0``, no thermal softening:
``sigma_y = sigma_0 + H eps_p``), ``power_law_hardening`` (Ludwik: ``sigma_y = sigma_0 +
K eps_p^n``) and ``johnson_cook`` (all three factors).

The return (radial return with a nonlinear, rate-dependent yield surface; Simo & Hughes 1998,
section 3.3; the viscoplastic consistency form of Wang et al. 1997 for the rate): with the
trial deviator ``S_t`` (the elastic update of the stage) and ``sigma_t = sqrt(3/2 S_t:S_t)``,
the stage is elastic if ``sigma_t <= sigma_y(eps_p0, 0, T)``; otherwise the increment of
equivalent plastic strain ``d`` solves, by backward Euler in strain and rate,

    g(d) = sigma_t - 3 mu d - sigma_y(eps_p0 + d, d / dt, T) = 0,     0 < d < sigma_t / (3 mu)

(``g`` falls monotonically from ``g(0) > 0`` to ``g(sigma_t / 3 mu) = -sigma_y <= 0``: one
root, bracketed).  It is found by Newton's method kept inside the bracket (a bisection step
wherever Newton would leave it, as at ``eps_p = 0`` with ``n < 1``, where the slope is
infinite), to ``|g| <= 1e-12 sigma_t``.  Then ``S = S_t sigma_y / sigma_t``,
``eps_p = eps_p0 + d`` and the plastic strain rate is ``d / dt``.  The temperature of the
flow stress is the one at the start of the stage (explicit in T, as in most explicit
hydrocodes); the integrator then raises it by ``beta w_p / c_p``.  With linear hardening the
root is exact after one Newton step: ``d = (sigma_t - sigma_y0 - H eps_p0) / (3 mu + H)``.

The returned specific plastic work is, as for ``elastic_plastic``, ``sigma_y d / rho``: the
work of the returned stress on the plastic strain increment.
"""

from __future__ import annotations

import math

import numba as nb
from pydantic import Field

from ..columns import EQUIVALENT_PLASTIC_STRAIN, PLASTIC_STRAIN_RATE, TEMPERATURE
from ..registry import STRENGTH, Parameters, StrengthModel
from ..types import NonNegativeFloat, PositiveFloat
from .von_mises import double_contraction

#: relative tolerance of the return's residual, and its most iterations
TOLERANCE = 1e-12
MAX_ITERATIONS = 200


@nb.njit(inline="always", cache=True)
def thermal_factor(temperature, reference_temperature, melting_temperature, exponent):
    """``1 - T*^m``, ``T* = (T - T_r) / (T_melt - T_r)`` clipped to [0, 1]; 1 when
    ``T_melt <= T_r`` (no thermal softening)."""
    if melting_temperature <= reference_temperature:
        return 1.0
    t_star = (temperature - reference_temperature) / (melting_temperature
                                                      - reference_temperature)
    if t_star <= 0.0:
        return 1.0
    if t_star >= 1.0:
        return 0.0
    return 1.0 - t_star ** exponent


@nb.njit(inline="always", cache=True)
def flow_stress(eps, rate, A, B, n, C, rate0, thermal):
    """``(A + B eps^n)(1 + C ln max(rate / rate0, 1)) thermal`` (Pa)."""
    strain = A + B * eps ** n if eps > 0.0 else A
    if C > 0.0 and rate > rate0:
        return strain * (1.0 + C * math.log(rate / rate0)) * thermal
    return strain * thermal


@nb.njit(inline="always", cache=True)
def flow_stress_slope(eps, d, dt, A, B, n, C, rate0, thermal):
    """``d sigma_y / d d`` at ``eps = eps0 + d``, rate ``d / dt`` (inf where ``n < 1`` at
    ``eps = 0``)."""
    rate = d / dt
    log_rate = math.log(rate / rate0) if (C > 0.0 and rate > rate0) else 0.0
    rate_factor = 1.0 + C * log_rate
    if eps > 0.0:
        slope = B * n * eps ** (n - 1.0) * rate_factor
    elif B > 0.0 and n < 1.0:
        return math.inf
    elif B > 0.0 and n == 1.0:
        slope = B * rate_factor
    else:
        slope = 0.0
    if C > 0.0 and rate > rate0 and d > 0.0:
        slope += (A + B * eps ** n if eps > 0.0 else A) * C / d
    return slope * thermal


@nb.njit(inline="always", cache=True)
def hardening_return(S, rho, shear_modulus, state, dt, A, B, n, C, rate0, thermal):
    """The return described in the module docstring; ``S`` and ``state`` changed in place;
    returns the specific plastic work (J/kg)."""
    eps0 = state[EQUIVALENT_PLASTIC_STRAIN]
    ss = double_contraction(S)
    sigma_t = math.sqrt(1.5 * ss)
    if sigma_t <= flow_stress(eps0, 0.0, A, B, n, C, rate0, thermal):
        state[PLASTIC_STRAIN_RATE] = 0.0
        return 0.0
    three_mu = 3.0 * shear_modulus
    lo = 0.0
    hi = sigma_t / three_mu
    d = 0.5 * hi
    if B == 0.0 or n == 1.0:  # start from the linear-hardening root
        slope = B if n == 1.0 else 0.0
        d = (sigma_t - flow_stress(eps0, 0.0, A, B, n, 0.0, rate0, thermal)) / (
            three_mu + slope * thermal)
        d = min(max(d, 0.0), hi)
    dt_ = dt if dt > 0.0 else 1e-300
    for _ in range(MAX_ITERATIONS):
        g = sigma_t - three_mu * d - flow_stress(eps0 + d, d / dt_, A, B, n, C, rate0,
                                                 thermal)
        if abs(g) <= TOLERANCE * sigma_t:
            break
        if g > 0.0:
            lo = d
        else:
            hi = d
        if hi - lo <= 1e-15 * (hi + lo):
            break
        slope = flow_stress_slope(eps0 + d, d, dt_, A, B, n, C, rate0, thermal)
        step = g / (three_mu + slope)
        trial = d + step
        if not (lo < trial < hi) or math.isinf(slope):
            trial = 0.5 * (lo + hi)
        d = trial
    sigma_y = sigma_t - three_mu * d
    if sigma_y < 0.0:
        sigma_y = 0.0
    f = sigma_y / sigma_t
    for a in range(3):
        for b in range(3):
            S[a, b] *= f
    state[EQUIVALENT_PLASTIC_STRAIN] = eps0 + d
    state[PLASTIC_STRAIN_RATE] = d / dt_
    return sigma_y * d / rho


# -- linear hardening ------------------------------------------------------------------------


class LinearHardeningParameters(Parameters):
    """``[materials.X.linear_hardening]``."""

    yield_stress: PositiveFloat = Field(description="initial yield stress sigma_0 (Pa)")
    hardening_modulus: NonNegativeFloat = Field(
        description="plastic modulus H = d sigma_y / d eps_p (Pa)")


@nb.njit(cache=True)
def linear_return(S, rho, pressure, shear_modulus, params, state, own, dt):
    """``sigma_y = sigma_0 + H eps_p``: :func:`hardening_return` with ``n = 1``, ``C = 0``."""
    return hardening_return(S, rho, shear_modulus, state, dt, params[0], params[1], 1.0, 0.0,
                            1.0, 1.0)


LINEAR_HARDENING = STRENGTH.register(StrengthModel(
    name="linear_hardening", return_map=linear_return, parameters=LinearHardeningParameters,
    columns=("yield_stress", "hardening_modulus"),
    coefficients=lambda p, constants: (p.yield_stress, p.hardening_modulus),
    source="Simo & Hughes (1998) section 3.3 (radial return, linear isotropic hardening)",
    description="von Mises plasticity, sigma_y = sigma_0 + H eps_p"))


# -- power-law hardening ---------------------------------------------------------------------


class PowerLawHardeningParameters(Parameters):
    """``[materials.X.power_law_hardening]``."""

    yield_stress: NonNegativeFloat = Field(description="initial yield stress sigma_0 (Pa)")
    strength_coefficient: PositiveFloat = Field(description="hardening coefficient K (Pa)")
    hardening_exponent: PositiveFloat = Field(le=1.0, description="hardening exponent n, "
                                              "in (0, 1]")


@nb.njit(cache=True)
def power_law_return(S, rho, pressure, shear_modulus, params, state, own, dt):
    """``sigma_y = sigma_0 + K eps_p^n`` (Ludwik): :func:`hardening_return` with ``C = 0``."""
    return hardening_return(S, rho, shear_modulus, state, dt, params[0], params[1], params[2],
                            0.0, 1.0, 1.0)


POWER_LAW_HARDENING = STRENGTH.register(StrengthModel(
    name="power_law_hardening", return_map=power_law_return,
    parameters=PowerLawHardeningParameters,
    columns=("yield_stress", "strength_coefficient", "hardening_exponent"),
    coefficients=lambda p, constants: (p.yield_stress, p.strength_coefficient,
                                       p.hardening_exponent),
    source="Ludwik (1909); return as Simo & Hughes (1998) section 3.3",
    description="von Mises plasticity, sigma_y = sigma_0 + K eps_p^n"))


# -- Johnson-Cook ----------------------------------------------------------------------------


class JohnsonCookParameters(Parameters):
    """``[materials.X.johnson_cook]``: the constants of Johnson & Cook (1983) eq 1.  The
    melting temperature is the material's ``melting_temperature``; the temperature rise
    needs its ``specific_heat`` (and ``taylor_quinney``)."""

    yield_stress: PositiveFloat = Field(description="A: yield stress at the reference rate "
                                        "and temperature (Pa)")
    hardening_modulus: NonNegativeFloat = Field(description="B: strain-hardening modulus (Pa)")
    hardening_exponent: PositiveFloat = Field(le=1.0, description="n: strain-hardening "
                                              "exponent, in (0, 1]")
    strain_rate_coefficient: NonNegativeFloat = Field(description="C: strain-rate coefficient")
    reference_strain_rate: PositiveFloat = Field(
        1.0, description="rate0: the plastic strain rate of the quasi-static fit (1/s)")
    thermal_exponent: PositiveFloat = Field(description="m: thermal-softening exponent")
    reference_temperature: PositiveFloat = Field(
        293.15, description="T_r: the room temperature of T* (K)")


@nb.njit(cache=True)
def johnson_cook_return(S, rho, pressure, shear_modulus, params, state, own, dt):
    """Johnson-Cook flow stress: :func:`hardening_return` with ``params = (A, B, n, C,
    rate0, m, T_r, T_melt)``, the temperature of the stage's start."""
    thermal = thermal_factor(state[TEMPERATURE], params[6], params[7], params[5])
    return hardening_return(S, rho, shear_modulus, state, dt, params[0], params[1], params[2],
                            params[3], params[4], thermal)


def _johnson_cook_columns(p: JohnsonCookParameters, constants) -> tuple[float, ...]:
    return (p.yield_stress, p.hardening_modulus, p.hardening_exponent,
            p.strain_rate_coefficient, p.reference_strain_rate, p.thermal_exponent,
            p.reference_temperature, constants.melting_temperature)


JOHNSON_COOK = STRENGTH.register(StrengthModel(
    name="johnson_cook", return_map=johnson_cook_return, parameters=JohnsonCookParameters,
    columns=("yield_stress", "hardening_modulus", "hardening_exponent",
             "strain_rate_coefficient", "reference_strain_rate", "thermal_exponent",
             "reference_temperature", "melting_temperature"),
    coefficients=_johnson_cook_columns, needs=("melting_temperature", "specific_heat"),
    source="Johnson & Cook (1983) eq 1",
    description="Johnson-Cook strength: strain hardening, strain rate, thermal softening"))
