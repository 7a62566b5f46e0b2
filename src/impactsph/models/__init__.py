"""Material and viscosity models, each one module registered by name (:mod:`.registry`).

Importing this package registers the built-in ones:

- equations of state (:mod:`.eos`): ``linear`` (eq 6), ``mie_gruneisen`` (eqs 7-12);
- strength models (:mod:`.strength`): ``bar``, ``elastic``, ``elastic_plastic`` (von Mises,
  eqs 17-18);
- viscosity schemes (:mod:`.viscosity`): ``av`` (Monaghan, eqs 29-30), ``ac`` (the Shaw-Reid
  acceleration correction, eqs 31-37).

A model of your own is one module that builds an :class:`EquationOfState`,
:class:`StrengthModel` or :class:`ViscosityScheme` and calls :func:`register`; see
docs/architecture.md.
"""

from . import eos, strength, viscosity  # noqa: F401
from .registry import (
    EOS,
    STRENGTH,
    VISCOSITY,
    ElasticConstants,
    EquationOfState,
    Parameters,
    StrengthModel,
    ViscosityScheme,
    register,
)

__all__ = ["EOS", "STRENGTH", "VISCOSITY", "ElasticConstants", "EquationOfState",
           "Parameters", "StrengthModel", "ViscosityScheme", "register"]
