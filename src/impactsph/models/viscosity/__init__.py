"""Viscosity schemes, one module each; importing this package registers them (in this
order, which is the order of their kind codes and of the error messages' lists)."""

# isort: off
from . import correction, monaghan, switches  # noqa: F401
from . import reconstruction  # noqa: F401  (registered last: the older codes stay)
# isort: on
