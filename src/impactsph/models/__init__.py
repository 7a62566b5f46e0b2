"""Material and viscosity models, each one module registered by name (:mod:`.registry`).

Importing this package registers the built-in ones:

- equations of state (:mod:`.eos`): ``linear`` (eq 6), ``mie_gruneisen`` (eqs 7-12),
  ``tillotson``;
- strength models (:mod:`.strength`): ``bar``, ``elastic``, ``elastic_plastic`` (von Mises,
  eqs 17-18), ``linear_hardening``, ``power_law_hardening``, ``johnson_cook``;
- damage models (:mod:`.damage`): ``none``, ``johnson_cook_damage``, ``grady_kipp``;
- viscosity schemes (:mod:`.viscosity`): ``av`` (Monaghan, eqs 29-30), ``ac`` (the Shaw-Reid
  acceleration correction, eqs 31-37), the switches ``balsara``, ``morris_monaghan``,
  ``cullen_dehnen``, ``ac_pairwise`` and ``ac_optimised``, and ``reconstruction`` (the
  velocity jump reconstructed to the pair's midpoint; docs/dissipation.md).

A model of your own is one module that builds an :class:`EquationOfState`,
:class:`StrengthModel`, :class:`DamageModel` or :class:`ViscosityScheme` and calls
:func:`register`; see docs/architecture.md.
"""

from . import damage, eos, strength, viscosity  # noqa: F401
from .registry import (
    DAMAGE,
    EOS,
    STRENGTH,
    VISCOSITY,
    DamageModel,
    ElasticConstants,
    EquationOfState,
    Parameters,
    StrengthModel,
    ViscosityScheme,
    register,
)

__all__ = ["DAMAGE", "EOS", "STRENGTH", "VISCOSITY", "DamageModel", "ElasticConstants",
           "EquationOfState",
           "Parameters", "StrengthModel", "ViscosityScheme", "register"]
