"""Viscosity schemes, one module each; importing this package registers them."""

from . import correction, monaghan, switches  # noqa: F401
