"""Strength models, one module each; importing this package registers them."""

from . import elastic, hardening, von_mises  # noqa: F401
