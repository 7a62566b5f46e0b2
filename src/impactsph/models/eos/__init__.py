"""Equations of state, one module each; importing this package registers them."""

from . import linear, mie_gruneisen  # noqa: F401
