"""Particle state: structure-of-arrays, SI units, one layout for 1D, 2D and 3D."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np


@dataclass
class ParticleState:
    """All per-particle fields of a run.

    Vectors have shape ``(n, dim)``; the deviatoric stress is always ``(n, 3, 3)`` so that the
    out-of-plane component of plane strain (``S_zz``) is carried: it enters the von Mises norm
    (eqs 17-18; the plane-strain Taylor bar of section 5.2; see ``docs/modelling.md``,
    "Deviatoric stress").
    """

    position: np.ndarray  #: (n, dim) m
    velocity: np.ndarray  #: (n, dim) m/s
    density: np.ndarray  #: (n,) kg/m^3
    specific_energy: np.ndarray  #: (n,) J/kg, specific internal energy
    deviatoric_stress: np.ndarray  #: (n, 3, 3) Pa, Cauchy convention (tension positive)
    mass: np.ndarray  #: (n,) kg (kg/m per unit depth in 2D, kg/m^2 per unit section in 1D)
    smoothing_length: np.ndarray  #: (n,) m
    body: np.ndarray  #: (n,) int32 body index
    material: np.ndarray  #: (n,) int32 row of the material table
    clamped: np.ndarray  #: (n,) bool, held at zero velocity
    plastic_work: np.ndarray = field(default=None)  #: (n,) J/kg dissipated by yielding
    initial_position: np.ndarray = field(default=None)  #: (n, dim) m, position at t = 0
    #: (n, k) the material state: the equivalent plastic strain, its rate, the temperature
    #: and the damage (:mod:`impactsph.models.columns`), then the strength and damage models'
    #: own state (:class:`impactsph.materials.TableLayout`); a built problem's has the columns
    #: its models use (``TableLayout.state_width_of``); default zeros, the registered layout's
    #: width (every model's columns)
    material_state: np.ndarray = field(default=None)
    #: (n, dim) m/s^2, the hourglass control's acceleration (docs/stabilisation.md); (n, 0)
    #: when the control is off
    hourglass_acceleration: np.ndarray = field(default=None)
    #: (n,) the factor on each particle's artificial viscosity that a viscosity switch sets
    #: (docs/dissipation.md): ``Pi_ij`` is multiplied by ``(f_i + f_j) / 2``; 1 without a switch
    #: (a :class:`~impactsph.simulation.Simulation` without one holds it, and the memory, as a
    #: read-only view of the one number: no pass reads them)
    viscosity_factor: np.ndarray = field(default=None)
    #: (n,) what a viscosity switch keeps of a particle from one evaluation to the next (e.g.
    #: Cullen & Dehnen's: the velocity divergence, 1/s); 0 without a switch that keeps one
    viscosity_memory: np.ndarray = field(default=None)
    #: (n,) kg: inertia carried by a particle beyond its own mass, e.g. a rigid tip mass
    #: (``bodies.tip_mass``, ``carried_as = "added_inertia"``).  It enters the particle's
    #: acceleration, ``F_i / (m_i + added_i)``, its kinetic energy and its momentum, but not
    #: its volume ``m_i / rho_i`` nor its internal energy; zeros by default (a
    #: :class:`~impactsph.simulation.Simulation` without added mass holds them, and the
    #: memory, as a read-only view of the one zero: the passes read the inertia)
    added_mass: np.ndarray = field(default=None)
    time: float = 0.0
    step: int = 0
    #: the time (s) of the rate evaluation that set ``viscosity_factor`` (a switch that evolves
    #: the factors integrates them over the time since)
    viscosity_factor_time: float = 0.0

    def __post_init__(self) -> None:
        if self.plastic_work is None:
            self.plastic_work = np.zeros(self.n)
        if self.initial_position is None:
            self.initial_position = self.position.copy()
        if self.material_state is None:
            from .materials import TableLayout  # the layout of the registered models
            from .models.columns import THICKNESS_RATIO

            self.material_state = np.zeros((self.n, TableLayout.registered().state_width))
            self.material_state[:, THICKNESS_RATIO] = 1.0
        if self.hourglass_acceleration is None:
            self.hourglass_acceleration = np.zeros((self.n, 0))
        if self.viscosity_factor is None:
            self.viscosity_factor = np.ones(self.n)
        if self.viscosity_memory is None:
            self.viscosity_memory = np.zeros(self.n)
        if self.added_mass is None:
            self.added_mass = np.zeros(self.n)

    @property
    def n(self) -> int:
        """Number of particles."""
        return int(self.position.shape[0])

    @property
    def dim(self) -> int:
        """Spatial dimension (1, 2 or 3)."""
        return int(self.position.shape[1])

    @property
    def material_density(self) -> np.ndarray:
        """The material's density (kg/m^3): ``density`` over the thickness ratio ``t / t0``.
        They differ in plane stress only, where ``density`` is the mass per unit area over the
        initial thickness (the other models keep the ratio 1)."""
        from .models.columns import THICKNESS_RATIO

        return self.density / self.material_state[:, THICKNESS_RATIO]

    def check_shapes(self) -> None:
        """Raise :class:`ValueError` naming the first field that is not an array of this
        state's shape: ``(n, dim)`` for the vectors, ``(n, 3, 3)`` for the deviator, ``(n,
        k)`` for the material state and the hourglass acceleration, ``(n,)`` for the rest,
        ``n`` and ``dim`` those of ``position``.  The compiled passes index them without
        bounds checks, so an array replaced with another shape (a caller's, between two
        pieces of a run or in a callback) is refused here first."""
        x = self.position
        if not isinstance(x, np.ndarray) or x.ndim != 2 or not 1 <= x.shape[1] <= 3:
            raise ValueError(f"state.position: an array of shape (n, dim), dim 1, 2 or 3; "
                             f"got {_described(x)}")
        n, dim = x.shape
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("position", "time", "step", "viscosity_factor_time"):
                continue
            if f.name in ("velocity", "initial_position"):
                need = (n, dim)
            elif f.name == "deviatoric_stress":
                need = (n, 3, 3)
            elif f.name in ("material_state", "hourglass_acceleration"):
                need = (n, value.shape[1] if isinstance(value, np.ndarray) and value.ndim == 2
                        else "k")
            else:
                need = (n,)
            if not isinstance(value, np.ndarray) or value.shape != need:
                raise ValueError(f"state.{f.name}: this state's {n} particles in {dim}D need "
                                 f"an array of shape {need}; got {_described(value)}")

    def copy(self) -> ParticleState:
        """A deep copy."""
        kwargs = {}
        for f in fields(self):
            val = getattr(self, f.name)
            kwargs[f.name] = val.copy() if isinstance(val, np.ndarray) else val
        return ParticleState(**kwargs)

    def arrays(self) -> dict[str, np.ndarray]:
        """The per-particle arrays by name (for checkpoints and snapshots)."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)}

    @property
    def inertial_mass(self) -> np.ndarray:
        """``mass + added_mass`` (kg): what the particle's momentum and kinetic energy count;
        the masses themselves (not a copy: read it, do not write it) where no particle
        carries added mass."""
        return self.mass + self.added_mass if self.added_mass.any() else self.mass

    def inertia_fraction(self) -> np.ndarray | None:
        """``m_i / (m_i + added_i)``, the factor that turns a particle's force per own mass
        into its acceleration; None where no particle carries added mass."""
        if not self.added_mass.any():
            return None
        return self.mass / self.inertial_mass

    def kinetic_energy(self) -> float:
        """``sum 1/2 (m + added) |v|^2`` (J; J/m per unit depth in 2D, J/m^2 per unit section
        in 1D)."""
        return 0.5 * math.fsum(self.inertial_mass * np.einsum("ia,ia->i", self.velocity,
                                                              self.velocity))

    def internal_energy(self) -> float:
        """``sum m e``."""
        return math.fsum(self.mass * self.specific_energy)

    def momentum(self) -> np.ndarray:
        """``sum (m + added) v`` (vector)."""
        return self.inertial_mass @ self.velocity


def _described(value: object) -> str:
    """An array by its shape, anything else by its type."""
    if isinstance(value, np.ndarray):
        return f"shape {value.shape}"
    return f"a {type(value).__name__}"
