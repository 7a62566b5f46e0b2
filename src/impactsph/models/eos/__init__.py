"""Equations of state, one module each; importing this package registers them."""

from . import linear, mie_gruneisen, tillotson  # noqa: F401
