"""Materials resolved from a case, and their packed form for the compiled kernels: the
material table, one row of floats per material.

A row holds the columns every kernel reads (:mod:`impactsph.models.columns`), then the columns
of the material's equation of state, of its strength model and of its damage model, as those
models declare them (:mod:`impactsph.models`).  :class:`TableLayout` says where each block
starts; it is the same for every material of a run, sized for the widest registered model, and
the generated passes (:mod:`impactsph.physics.passes`) are compiled for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import CaseError
from .models import DAMAGE, EOS, STRENGTH, ElasticConstants
from .models.columns import (  # noqa: F401  (re-exported: the kernels import them from here)
    BULK,
    COMMON_COLUMNS,
    COMMON_STATE,
    DAMAGE_KIND,
    EOS_KIND,
    HEAT_PER_WORK,
    LONGITUDINAL_SPEED,
    MELTING_TEMPERATURE,
    RHO0,
    SHEAR,
    STRENGTH_KIND,
    TEMPERATURE,
    WAVE_MODULUS,
    YOUNGS,
)


@dataclass(frozen=True)
class TableLayout:
    """Where the models' blocks start in a row of the material table, and the layout of the
    per-particle material state (:attr:`impactsph.state.ParticleState.material_state`): the
    common state, then the strength model's own, then the damage model's own."""

    eos_width: int
    strength_width: int
    damage_width: int
    strength_state_width: int
    damage_state_width: int

    @classmethod
    def registered(cls) -> TableLayout:
        """The layout that fits every registered model."""
        return cls(max((len(m.columns) for m in EOS), default=0),
                   max((len(m.columns) for m in STRENGTH), default=0),
                   max((len(m.columns) for m in DAMAGE), default=0),
                   max((len(m.state) for m in STRENGTH), default=0),
                   max((len(m.state) for m in DAMAGE), default=0))

    @property
    def strength_state(self) -> int:
        """First column of the strength model's own state."""
        return len(COMMON_STATE)

    @property
    def damage_state(self) -> int:
        """First column of the damage model's own state."""
        return self.strength_state + self.strength_state_width

    @property
    def state_width(self) -> int:
        """Width of the material state (at least one own column per model, so that slices
        are never empty)."""
        return self.damage_state + max(self.damage_state_width, 1)

    @property
    def eos_params(self) -> int:
        """First column of the equation of state's parameters."""
        return len(COMMON_COLUMNS)

    @property
    def strength_params(self) -> int:
        """First column of the strength model's parameters."""
        return self.eos_params + self.eos_width

    @property
    def damage_params(self) -> int:
        """First column of the damage model's parameters."""
        return self.strength_params + max(self.strength_width, 1)

    @property
    def n_columns(self) -> int:
        """Length of a row (at least one column per block, so that slices are never empty)."""
        return self.damage_params + max(self.damage_width, 1)

    def state_width_of(self, strength: list[str] | tuple[str, ...],
                       damage: list[str] | tuple[str, ...]) -> int:
        """Width of the material state for a case whose materials use the strength models
        ``strength`` and the damage models ``damage`` (registered names): the common
        columns, then the strength models' block if one of the case's has a state of its
        own, then the damage models' block if one of the case's has.  The blocks keep
        their places of the registered layout (the kernels' column constants), so what is
        left out is the trailing blocks that no material of the case uses: an elastic or
        plastic case without a damage model carries the 5 common columns, not the
        registered union's :attr:`state_width` (48 bytes a particle less in the state and
        the integrator's copy at the step's start)."""
        if any(DAMAGE[name].state for name in damage):
            return self.state_width
        if any(STRENGTH[name].state for name in strength):
            return self.damage_state
        return self.strength_state

    def state_width_of_table(self, table: np.ndarray) -> int:
        """:meth:`state_width_of` for the materials of a material table (their kind codes)."""
        strength = STRENGTH.names()
        damage = DAMAGE.names()
        return self.state_width_of([strength[int(k)] for k in table[:, STRENGTH_KIND]],
                                   [damage[int(k)] for k in table[:, DAMAGE_KIND]])

    def state_names(self, material: MaterialModel) -> dict[str, int]:
        """The material state's columns that mean something for ``material``, by name."""
        names = {name: k for k, name in enumerate(COMMON_STATE)}
        for k, name in enumerate(STRENGTH[material.model].state):
            names[name] = self.strength_state + k
        for k, name in enumerate(DAMAGE[material.damage].state):
            names[name] = self.damage_state + k
        return names


@dataclass(frozen=True)
class MaterialModel:
    """A case material resolved to SI constants and its models' table columns."""

    name: str
    model: str  #: the strength model's registered name
    eos: str  #: the equation of state's registered name
    density: float
    youngs_modulus: float
    poisson_ratio: float
    shear_modulus: float
    bulk_modulus: float
    eos_columns: tuple[float, ...] = ()
    strength_columns: tuple[float, ...] = ()
    damage: str = "none"  #: the damage model's registered name
    damage_columns: tuple[float, ...] = ()
    specific_heat: float = 0.0  #: J/(kg K); 0: the temperature does not change
    taylor_quinney: float = 0.9  #: fraction of the plastic work that heats
    melting_temperature: float = 0.0  #: K; 0: not given
    temperature: float = 293.15  #: initial temperature (K)
    #: the validated damage parameters (for the damage model's initial_state)
    damage_parameters: Any = field(default=None, compare=False, hash=False)

    @property
    def yield_stress(self) -> float:
        """The (initial) yield stress (Pa): the strength model's column named
        ``yield_stress``; infinite for a model without one."""
        columns = STRENGTH[self.model].columns
        if "yield_stress" in columns:
            return self.strength_columns[columns.index("yield_stress")]
        return math.inf

    def wave_modulus(self, wave_speed: str) -> float:
        """Modulus ``M`` with ``c = sqrt(M / rho)``: ``E`` for the paper's bar-wave speed
        (eq 26), ``K + 4/3 mu`` for the longitudinal (P-wave) speed."""
        if STRENGTH[self.model].uniaxial_stress or wave_speed == "bar":
            return self.youngs_modulus
        return self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus

    def row(self, wave_speed: str, layout: TableLayout) -> np.ndarray:
        """This material as one row of the kernels' table."""
        r = np.zeros(layout.n_columns)
        r[RHO0] = self.density
        r[BULK] = self.bulk_modulus
        r[SHEAR] = self.shear_modulus
        r[WAVE_MODULUS] = self.wave_modulus(wave_speed)
        r[EOS_KIND] = EOS.index(self.eos)
        r[STRENGTH_KIND] = STRENGTH.index(self.model)
        r[DAMAGE_KIND] = DAMAGE.index(self.damage)
        r[YOUNGS] = self.youngs_modulus
        r[HEAT_PER_WORK] = (self.taylor_quinney / self.specific_heat
                            if self.specific_heat > 0.0 else 0.0)
        r[MELTING_TEMPERATURE] = self.melting_temperature
        r[LONGITUDINAL_SPEED] = math.sqrt((self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus)
                                          / self.density)
        r[layout.eos_params: layout.eos_params + len(self.eos_columns)] = self.eos_columns
        r[layout.strength_params: layout.strength_params + len(self.strength_columns)] = \
            self.strength_columns
        r[layout.damage_params: layout.damage_params + len(self.damage_columns)] = \
            self.damage_columns
        return r


def resolve_material(name: str, material: Any) -> MaterialModel:
    """Constants of a validated case material (``config.Material``): ``mu = E / (2(1 + nu))``
    unless given, ``K = E / (3(1 - 2 nu))``; for a uniaxial-stress model (the 1D ``bar``)
    ``K = E`` and ``mu = 0``; the models' table columns from their ``coefficients``."""
    E, nu = material.youngs_modulus, material.poisson_ratio
    strength, eos = STRENGTH[material.model], EOS[material.eos]
    if strength.uniaxial_stress:
        mu, K = 0.0, E
    else:
        mu = (material.shear_modulus if material.shear_modulus is not None
              else E / (2.0 * (1.0 + nu)))
        K = E / (3.0 * (1.0 - 2.0 * nu))
    melting = float(material.melting_temperature or 0.0)
    specific_heat = float(material.specific_heat or 0.0)
    constants = ElasticConstants(material.density, E, nu, K, mu, melting, specific_heat)
    damage = DAMAGE[material.damage]

    def columns(model: Any, parameters: Any, key: str) -> tuple[float, ...]:
        # (a model's own code: what it gets wrong is said in one line, as the case's field)
        if model.coefficients is None:
            return ()
        where = f"materials.{name}.{key} = {model.name!r}"
        try:
            values = tuple(float(c) for c in model.coefficients(parameters, constants))
        except Exception as exc:  # noqa: BLE001 - any failure of a model's code, in one line
            raise CaseError(f"{where}: its coefficients(parameters, constants) failed "
                            f"({type(exc).__name__}: {exc})".replace("\n", " ")) from None
        if len(values) != len(model.columns):
            raise CaseError(f"{where}: its coefficients gave {len(values)} value"
                            f"{'s' * (len(values) != 1)} for its {len(model.columns)} "
                            f"columns {model.columns}")
        return values

    return MaterialModel(
        name=name, model=material.model, eos=material.eos, density=material.density,
        youngs_modulus=E, poisson_ratio=nu, shear_modulus=mu, bulk_modulus=K,
        eos_columns=columns(eos, material.eos_parameters(), "eos"),
        strength_columns=columns(strength, material.strength_parameters(), "model"),
        damage=material.damage,
        damage_columns=columns(damage, material.damage_parameters(), "damage"),
        specific_heat=specific_heat, taylor_quinney=float(material.taylor_quinney),
        melting_temperature=melting, temperature=float(material.temperature),
        damage_parameters=material.damage_parameters())


def case_materials(case: Any) -> list[MaterialModel]:
    """The case's ``[materials]``, resolved (library entries included), in the case's order:
    the rows of its material table, whose index a particle's ``material`` is."""
    return [resolve_material(name, case.materials[name]) for name in case.materials]


def material_table(materials: list[MaterialModel], wave_speed: str,
                   layout: TableLayout | None = None) -> np.ndarray:
    """Stack the materials' rows into the ``(n_materials, layout.n_columns)`` table."""
    layout = layout or TableLayout.registered()
    return np.ascontiguousarray(np.stack([m.row(wave_speed, layout) for m in materials]))


def carried_pressure(pressure: np.ndarray, damage: np.ndarray) -> np.ndarray:
    """The pressure a particle carries (Pa): its EOS pressure, in tension times ``1 - D``
    (as :func:`impactsph.physics.passes.particle_record` gives the forces)."""
    return np.where(pressure < 0.0, pressure * (1.0 - damage), pressure)


def carried_von_mises(deviatoric_stress: np.ndarray, damage: np.ndarray) -> np.ndarray:
    """The von Mises stress a particle carries (Pa): that of its deviator times ``1 - D``."""
    from .models.strength.von_mises import von_mises_stress

    return (1.0 - damage) * von_mises_stress(deviatoric_stress)
