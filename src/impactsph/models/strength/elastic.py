"""Elastic bodies: no strength limit.

- ``elastic``: linear (hypo)elastic deviatoric stress, advanced by the Jaumann rate (eq 14,
  :mod:`impactsph.physics.stress_rate`) with the shear modulus ``mu = E / (2 (1 + nu))`` (or
  the one given), and any equation of state.
- ``bar``: the one-dimensional bar of the paper's Example 1 (uniaxial stress): the whole
  stress is the pressure of the linear EOS with ``K = E``, no deviatoric stress, and waves
  travel at the bar speed ``sqrt(E / rho)``.
"""

from __future__ import annotations

from ..registry import STRENGTH, StrengthModel

ELASTIC = STRENGTH.register(StrengthModel(
    name="elastic", description="linear elastic deviatoric stress (Jaumann rate, eq 14)",
    source="Shaw & Reid (2009) eqs 13-16"))

BAR = STRENGTH.register(StrengthModel(
    name="bar", description="1D uniaxial stress: P = E (rho/rho0 - 1), no deviatoric stress",
    uniaxial_stress=True, dimensions=(1,), equations_of_state=("linear",),
    source="Shaw & Reid (2009) section 5.1"))
