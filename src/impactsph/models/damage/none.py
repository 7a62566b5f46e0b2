"""No damage: the damage of every particle stays 0 (the default, ``damage = "none"``)."""

from __future__ import annotations

from ..registry import DAMAGE, DamageModel

NONE = DAMAGE.register(DamageModel(name="none", description="no damage"))
