"""Johnson-Cook ductile damage (Johnson & Cook 1985, eqs 1-2).

The strain to fracture at stress triaxiality ``sigma* = sigma_m / sigma_eq = -P / sigma_eq``,
plastic strain rate ``rate`` and homologous temperature ``T*``::

    eps_f = [D1 + D2 exp(D3 sigma*)] [1 + D4 ln max(rate / rate0, 1)] [1 + D5 T*]

and the damage indicator accumulates over the increments of equivalent plastic strain::

    D_JC = sum d eps_p / eps_f                                        (Johnson & Cook 1985, eq 2)

The particle fails when ``D_JC`` reaches 1: its damage (the common state's ``damage``) jumps
from 0 to 1, so that it keeps its pressure in compression only and no deviatoric stress
(:func:`impactsph.physics.passes.particle_record`).  Until then the stress is undamaged, as in
Johnson & Cook (1985), who couple no softening to ``D_JC`` (LS-DYNA's ``*MAT_015`` does the
same).  ``sigma_eq`` is that of the stress after the return; a stage without plastic strain
adds nothing.  ``eps_f`` is kept above ``1e-6`` (a negative bracket, at high triaxiality with
``D1 < 0``, is immediate failure).  ``T* = (T - T_r) / (T_melt - T_r)`` clipped to [0, 1],
with the material's ``melting_temperature`` (0: no temperature term).  Johnson & Cook (1985)
also give a spall criterion for ``sigma* > 1.5``; it is not modelled.
"""

from __future__ import annotations

import math

import numba as nb
from pydantic import Field

from ..columns import DAMAGE, MELTING_TEMPERATURE, PLASTIC_STRAIN_RATE, TEMPERATURE
from ..registry import DAMAGE as DAMAGE_MODELS
from ..registry import DamageModel, Parameters
from ..types import FiniteFloat, PositiveFloat

#: the smallest strain to fracture (a non-positive bracket fails the particle at once)
SMALLEST_FRACTURE_STRAIN = 1e-6


class JohnsonCookDamageParameters(Parameters):
    """``[materials.X.johnson_cook_damage]``: the constants of Johnson & Cook (1985) eq 1."""

    d1: FiniteFloat = Field(description="D1")
    d2: FiniteFloat = Field(description="D2")
    d3: FiniteFloat = Field(description="D3 (multiplies the triaxiality; negative)")
    d4: FiniteFloat = Field(0.0, description="D4 (strain-rate term)")
    d5: FiniteFloat = Field(0.0, description="D5 (temperature term)")
    reference_strain_rate: PositiveFloat = Field(1.0, description="rate0 (1/s)")
    reference_temperature: PositiveFloat = Field(293.15, description="T_r of T* (K)")


@nb.njit(inline="always", cache=True)
def fracture_strain(triaxiality, rate, t_star, d1, d2, d3, d4, d5, rate0):
    """``eps_f`` of Johnson & Cook (1985) eq 1 (at least ``SMALLEST_FRACTURE_STRAIN``)."""
    eps_f = d1 + d2 * math.exp(d3 * triaxiality)
    if rate > rate0:
        eps_f *= 1.0 + d4 * math.log(rate / rate0)
    eps_f *= 1.0 + d5 * t_star
    return max(eps_f, SMALLEST_FRACTURE_STRAIN)


@nb.njit(cache=True)
def update(S, pressure, rho, size, dt, plastic_strain_increment, row, params, state, own):
    """``own[0] += d eps_p / eps_f``; ``state[DAMAGE] = 1`` once it reaches 1."""
    if state[DAMAGE] >= 1.0:
        return
    if plastic_strain_increment <= 0.0:
        return
    ss = 0.0
    for a in range(3):
        for b in range(3):
            ss += S[a, b] * S[a, b]
    seq = math.sqrt(1.5 * ss)
    triaxiality = -pressure / seq if seq > 0.0 else 0.0
    t_melt = row[MELTING_TEMPERATURE]
    t_ref = params[6]
    t_star = 0.0
    if t_melt > t_ref:
        t_star = min(max((state[TEMPERATURE] - t_ref) / (t_melt - t_ref), 0.0), 1.0)
    eps_f = fracture_strain(triaxiality, state[PLASTIC_STRAIN_RATE], t_star, params[0],
                            params[1], params[2], params[3], params[4], params[5])
    own[0] += plastic_strain_increment / eps_f
    if own[0] >= 1.0:
        state[DAMAGE] = 1.0


JOHNSON_COOK_DAMAGE = DAMAGE_MODELS.register(DamageModel(
    name="johnson_cook_damage", update=update, parameters=JohnsonCookDamageParameters,
    columns=("d1", "d2", "d3", "d4", "d5", "reference_strain_rate", "reference_temperature"),
    coefficients=lambda p, constants: (p.d1, p.d2, p.d3, p.d4, p.d5, p.reference_strain_rate,
                                       p.reference_temperature),
    state=("johnson_cook_damage",), source="Johnson & Cook (1985) eqs 1-2",
    description="ductile failure when sum(d eps_p / eps_f) reaches 1"))
