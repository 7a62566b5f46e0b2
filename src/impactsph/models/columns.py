"""Fixed column indices shared by the kernels and the models: the common columns of a row of
the material table, and the common columns of a particle's material state.

A row of the material table (:mod:`impactsph.materials`) begins with the columns every material
has, in this order, then the blocks of its equation of state, strength model and damage model.
A particle's material state (:attr:`impactsph.state.ParticleState.material_state`) begins with
the fields every material carries, then the strength model's own state, then the damage
model's own state (each model declares its own, ``StrengthModel.state``,
``DamageModel.state``).
"""

from __future__ import annotations

#: Columns every material has: reference density rho0 (kg/m^3), bulk modulus K (Pa), shear
#: modulus mu (Pa), the modulus M of the wave speed ``c = sqrt(M / rho)`` (eq 26), the kind
#: codes of its equation of state, strength and damage models (their positions in the
#: registries), Young's modulus E (Pa), the heating per unit plastic work ``beta / c_p``
#: (K kg/J: the Taylor-Quinney factor over the specific heat; 0 keeps the temperature), the
#: melting temperature (K; 0 when not given) and the longitudinal wave speed at rho0
#: ``sqrt((K + 4/3 mu) / rho0)`` (m/s).
(RHO0, BULK, SHEAR, WAVE_MODULUS, EOS_KIND, STRENGTH_KIND, DAMAGE_KIND, YOUNGS,
 HEAT_PER_WORK, MELTING_TEMPERATURE, LONGITUDINAL_SPEED) = range(11)
COMMON_COLUMNS = ("density", "bulk_modulus", "shear_modulus", "wave_modulus", "eos_kind",
                  "strength_kind", "damage_kind", "youngs_modulus", "heat_per_work",
                  "melting_temperature", "longitudinal_speed")

#: The material state every particle carries: the equivalent plastic strain (-), its rate
#: over the last integrator stage (1/s), the temperature (K) and the damage D in [0, 1] (the
#: fraction of the tensile pressure and of the deviatoric stress that is lost: a particle
#: with D = 1 carries pressure in compression only) and the thickness ratio t / t0 (plane
#: stress: the particle's thickness over its initial one; 1 in every other model).
EQUIVALENT_PLASTIC_STRAIN, PLASTIC_STRAIN_RATE, TEMPERATURE, DAMAGE, THICKNESS_RATIO = range(5)
COMMON_STATE = ("equivalent_plastic_strain", "plastic_strain_rate", "temperature", "damage",
                "thickness_ratio")
#: the number of common columns
CARRIED = len(COMMON_STATE)
#: the common columns a return map changes, the first ones: the equivalent plastic strain,
#: its rate and the temperature its plastic work heats (the step's start copy keeps these
#: where no other model changes the state and a material that yields heats:
#: :func:`impactsph.integrate.material_state_kept`)
RETURN_MAP_COLUMNS = TEMPERATURE + 1
#: of those, the ones a return map changes where its material does not heat (no specific
#: heat: the equivalent plastic strain and its rate)
PLASTIC_COLUMNS = PLASTIC_STRAIN_RATE + 1
#: the rate passes' ``carried`` array (every row, ghosts included): the common columns, then,
#: for a viscosity scheme with a switch, the particle's viscosity factor and its switch's
#: memory (``ParticleState.viscosity_factor``, ``ParticleState.viscosity_memory``; neither is
#: a material state, and the integrator touches neither).  Without a switch it is the
#: material state itself (``Solver._arrays``) or, with ghosts, the extended rows of which the
#: material state is a view (``Solver._allocate``); its first columns are the common ones:
#: the passes read columns 5 and 6 only with a switch.
VISCOSITY_FACTOR = CARRIED
VISCOSITY_MEMORY = CARRIED + 1
PASS_CARRIED = CARRIED + 2
#: units of the common state, for outputs
COMMON_STATE_UNITS = {"equivalent_plastic_strain": "", "plastic_strain_rate": "1/s",
                      "temperature": "K", "damage": "", "thickness_ratio": ""}
