"""Damage (failure) models, one module each; importing this package registers them:
``none``, ``johnson_cook_damage`` (ductile), ``grady_kipp`` (brittle, tensile)."""

from . import grady_kipp, johnson_cook, none  # noqa: F401
