"""Monaghan's viscosity on the velocity jump reconstructed to each pair's midpoint, with van
Leer's (or the minmod) slope limiter: ``scheme = "reconstruction"`` (Rosswog 2020, MNRAS
498:4230, section 2.3; Frontiere, Raskin & Owen 2017, J. Comput. Phys. 332:160).

``Pi_ij`` is eq 29 with ``v_ij . r_ij`` replaced, for two particles of the same body, by
the limited midpoint jump of :func:`impactsph.physics.reconstruction.reconstructed_approach`:
zero for a linear velocity field, the particles' own jump across a discontinuity.  The
viscosity then acts on what the particles' velocity gradients do not explain (a shock, the
particle-scale noise) and not on a smooth compression or shear; nothing is tuned per problem
(the coefficients are Monaghan's; docs/dissipation.md).  Contact pairs (another body, a
wall's ghosts) keep the particles' own jump.  The passes compute every particle's velocity
gradient before the pair pass (the registry's ``reconstruction`` flag).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ...physics.reconstruction import LIMITERS
from ..registry import VISCOSITY, ViscosityScheme
from .monaghan import MonaghanParameters
from .monaghan import pair_viscosity as monaghan_pair


class ReconstructionParameters(MonaghanParameters):
    """The ``[viscosity]`` fields of the reconstructing viscosity: Monaghan's and the slope
    limiter."""

    limiter: Literal["van_leer", "minmod"] = Field(
        "van_leer", description="slope limiter of the reconstruction: van Leer's (Rosswog "
        "2020 eq 23) or minmod (the smaller slope; more dissipative)")


RECONSTRUCTION = VISCOSITY.register(ViscosityScheme(
    name="reconstruction", pair_viscosity=monaghan_pair, parameters=ReconstructionParameters,
    pair_parameters=lambda v: (float(v.alpha1), float(v.alpha2), float(v.epsilon),
                               LIMITERS[v.limiter]),
    reconstruction=True,
    source="Rosswog (2020) MNRAS 498:4230, section 2.3; Frontiere, Raskin & Owen (2017) "
           "J Comput Phys 332:160 (the limited midpoint reconstruction; bounded by the "
           "particles' own jump: impactsph.physics.reconstruction)",
    description="Monaghan's viscosity on the limited midpoint reconstruction of the "
                "velocity jump"))
