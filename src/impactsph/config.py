"""The case schema: the tables of a case file as pydantic models, every field in SI units
(``docs/case-files.md``).

The models' names and parameters are not written here: :func:`schema` adds those of every
registered equation of state, strength model and viscosity scheme (:mod:`impactsph.models`) to
the classes below.  Reading files, ``--set`` overrides and one-line errors are
:mod:`impactsph.loading`'s.
"""

from __future__ import annotations

import math
import os
from typing import Annotated, Any, Literal

from pydantic import (
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

from .errors import CaseError  # noqa: F401  (defined there, kept importable from here)
from .models import DAMAGE, EOS, STRENGTH, VISCOSITY
from .models import registry as _registry
from .models.registry import Parameters as _Model
from .models.types import FiniteFloat, NonNegativeFloat, PositiveFloat


def _all_defaults(parameters: type[_Model]) -> bool:
    """Whether every field of a model's parameters has a default."""
    return not any(info.is_required() for info in parameters.model_fields.values())


def _components(n: int) -> str:
    """``"1 component"``, ``"2 components"``: a vector's length in a message."""
    return f"{n} component{'' if n == 1 else 's'}"


class Material(_Model):
    """A material: elastic constants, equation of state, strength model.

    The strength ``model`` and the ``eos`` are names of registered models
    (:mod:`impactsph.models`); each model's parameters are its part of this table: a sub-table
    named after the model (``[materials.iron.mie_gruneisen]``) or, for models registered
    ``flat``, fields of this table (``yield_stress`` of ``elastic_plastic``).  The fields of
    the registered models are added by :func:`schema`; this class holds the common ones."""

    model: str = Field(
        description="strength model: 'bar' (1D uniaxial stress with modulus E), 'elastic', "
        "'elastic_plastic' (von Mises perfect plasticity), or a registered one")
    density: PositiveFloat = Field(description="reference density rho0 (kg/m^3)")
    youngs_modulus: PositiveFloat = Field(description="Young's modulus E (Pa)")
    poisson_ratio: float = Field(0.3, gt=-1.0, lt=0.5, description="Poisson's ratio, in (-1, 0.5)")
    shear_modulus: PositiveFloat | None = Field(
        None, description="shear modulus mu (Pa); default E / (2 (1 + nu))"
    )
    eos: str = Field(
        "linear", description="equation of state: 'linear' (eq 6, K = E / (3 (1 - 2 nu))), "
        "'mie_gruneisen' (eqs 7-12), or a registered one")
    damage: str = Field(
        "none", description="damage model: 'none', 'johnson_cook_damage' (ductile), "
        "'grady_kipp' (brittle, tensile), or a registered one")
    specific_heat: PositiveFloat | None = Field(
        None, description="specific heat c_p (J/(kg K)); without it the temperature stays "
        "at its initial value")
    taylor_quinney: float = Field(
        0.9, ge=0.0, le=1.0, description="Taylor-Quinney factor beta: the fraction of the "
        "plastic work that heats, in [0, 1]")
    melting_temperature: PositiveFloat | None = Field(
        None, description="melting temperature T_melt (K), for thermal softening and damage")
    temperature: PositiveFloat = Field(293.15, description="initial temperature (K)")
    library: str | None = Field(
        None, description="the library material this one starts from (impactsph materials); "
        "its fields are filled in when the case is read, and any field given here overrides")

    @model_validator(mode="after")
    def _consistent(self) -> Material:
        eos, strength = EOS[self.eos], STRENGTH[self.model]
        damage = DAMAGE[self.damage]
        if damage.parameters is not None and getattr(self, damage.name, None) is None:
            if not _all_defaults(damage.parameters):
                raise ValueError(f"damage = {damage.name!r} needs a [{damage.name}] table")
            setattr(self, damage.name, damage.parameters())
        for model, kind in ((strength, "model"), (damage, "damage")):
            for need in model.needs:
                if getattr(self, need, None) is None:
                    info = Material.model_fields[need]
                    raise ValueError(f"{kind} = {model.name!r} needs {need} "
                                     f"({info.description})")
        if eos.parameters is not None and getattr(self, eos.name, None) is None:
            if _all_defaults(eos.parameters):  # a table of defaults may be left out
                setattr(self, eos.name, eos.parameters())
            else:
                raise ValueError(f"eos = {eos.name!r} needs a [{eos.name}] table")
        if strength.parameters is not None:
            if strength.flat:
                missing = [f for f, info in strength.parameters.model_fields.items()
                           if info.is_required() and getattr(self, f, None) is None]
                if missing:
                    raise ValueError(f"model = {strength.name!r} needs {missing[0]}")
            elif getattr(self, strength.name, None) is None:
                if not _all_defaults(strength.parameters):
                    raise ValueError(f"model = {strength.name!r} needs a [{strength.name}] "
                                     f"table")
                setattr(self, strength.name, strength.parameters())
        if strength.equations_of_state is not None and eos.name not in strength.equations_of_state:
            raise ValueError(f"model = {strength.name!r} takes eos = "
                             f"{' or '.join(map(repr, strength.equations_of_state))} only")
        return self

    def eos_parameters(self) -> Any:
        """The validated parameters of the selected equation of state (None if it has none)."""
        return getattr(self, self.eos, None) if EOS[self.eos].parameters is not None else None

    def damage_parameters(self) -> Any:
        """The validated parameters of the selected damage model (None if it has none)."""
        return (getattr(self, self.damage, None) if DAMAGE[self.damage].parameters is not None
                else None)

    def strength_parameters(self) -> Any:
        """The validated parameters of the selected strength model (None if it has none)."""
        strength = STRENGTH[self.model]
        if strength.parameters is None:
            return None
        if strength.flat:
            return strength.parameters.model_validate(
                {f: getattr(self, f) for f in strength.parameters.model_fields
                 if getattr(self, f, None) is not None})
        return getattr(self, strength.name)


class Block(_Model):
    """A lattice of particles filling an axis-aligned box (a line in 1D, a rectangle in 2D,
    a box in 3D); particles sit at cell centres.  Give either ``spacing`` (one value, or one
    per axis; ``round(size / spacing)`` particles per axis) or ``count`` (particles per axis;
    the spacing is then ``size / count``)."""

    type: Literal["block"] = "block"
    origin: list[FiniteFloat] = Field(description="lower corner (m)")
    size: list[PositiveFloat] = Field(description="edge lengths (m)")
    spacing: PositiveFloat | list[PositiveFloat] | None = Field(
        None, description="particle spacing dx (m), one value or one per axis")
    count: list[Annotated[int, Field(ge=1)]] | None = Field(
        None, description="particles per axis (instead of spacing)")

    @model_validator(mode="after")
    def _one_of(self) -> Block:
        if (self.spacing is None) == (self.count is None):
            raise ValueError("give exactly one of spacing and count")
        return self

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m)."""
        if self.count is not None:
            return [s / c for s, c in zip(self.size, self.count, strict=True)]
        if isinstance(self.spacing, list):
            return list(self.spacing)
        return [float(self.spacing)] * len(self.size)


def _lattice_holds_a_particle(radius: float, spacing: float) -> bool:
    """Whether a disk of ``radius`` holds a point of the lattice of :func:`geometry.disk_particles`
    (the nearest points are ``spacing / sqrt 2`` from the centre)."""
    return (radius / spacing) ** 2 >= 0.5


class Disk(_Model):
    """A disk of particles (2D): the cell centres of a square lattice of spacing ``spacing``
    that lie within ``radius`` of ``centre``.  The lattice has a cell corner at the centre, so
    the particles sit at ``centre + ((i + 1/2) dx, (j + 1/2) dx)``, symmetric about both axes
    through the centre."""

    type: Literal["disk"] = "disk"
    centre: list[FiniteFloat] = Field(description="centre of the disk (m)")
    radius: PositiveFloat = Field(description="radius (m)")
    spacing: PositiveFloat = Field(description="particle spacing dx (m)")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m)."""
        return [float(self.spacing)] * 2

    @model_validator(mode="after")
    def _not_empty(self) -> Disk:
        if not _lattice_holds_a_particle(self.radius, self.spacing):
            raise ValueError(f"radius = {self.radius!r} holds no particle at spacing = "
                             f"{self.spacing!r} (needs radius >= spacing / sqrt(2))")
        return self


def _annulus_holds_a_particle(inner: float, outer: float, spacing: float) -> bool:
    """Whether the closed annulus ``inner <= r <= outer`` holds a point of the lattice of
    :func:`geometry.disk_particles` (the points ``((i + 1/2) dx, (j + 1/2) dx)``): row by
    row, the point of smallest ``|x|`` at or beyond the inner circle."""
    ro, ri = outer / spacing, inner / spacing
    for j in range(int(math.ceil(ro))):  # the rows y = j + 1/2 >= 0 (symmetric about 0)
        y2 = (j + 0.5) ** 2
        if y2 > ro * ro:
            break
        xi = math.sqrt(max(ri * ri - y2, 0.0))
        x = max(0.5, math.ceil(xi - 0.5) + 0.5)
        if x * x + y2 <= ro * ro:
            return True
    return False


class Ring(_Model):
    """An annulus of particles (2D): the points of the :class:`Disk` lattice (spacing
    ``spacing``, a cell corner at ``centre``) whose distance from ``centre`` is at least
    ``inner_radius`` and at most ``outer_radius``.  The colliding rubber rings of Monaghan
    (2000) and Gray, Monaghan & Swift (2001) are two of them."""

    type: Literal["ring"] = "ring"
    centre: list[FiniteFloat] = Field(description="centre of the ring (m)")
    inner_radius: NonNegativeFloat = Field(description="inner radius (m); 0 gives a disk")
    outer_radius: PositiveFloat = Field(description="outer radius (m)")
    spacing: PositiveFloat = Field(description="particle spacing dx (m)")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m)."""
        return [float(self.spacing)] * 2

    @model_validator(mode="after")
    def _not_empty(self) -> Ring:
        if self.inner_radius >= self.outer_radius:
            raise ValueError(f"inner_radius = {self.inner_radius!r} must be less than "
                             f"outer_radius = {self.outer_radius!r}")
        if not _annulus_holds_a_particle(self.inner_radius, self.outer_radius, self.spacing):
            raise ValueError(f"the ring between {self.inner_radius!r} and "
                             f"{self.outer_radius!r} holds no particle at spacing = "
                             f"{self.spacing!r}")
        return self


class Sphere(_Model):
    """A ball of particles (3D): the cell centres of a cubic lattice of spacing ``spacing``,
    with a cell corner at ``centre``, that lie within ``radius`` of it (each of volume
    ``dx^3``); or, with ``arrangement = "shells"``, concentric shells whose outermost lies half
    a spacing inside the sphere (:func:`impactsph.geometry.sphere_shell_particles`)."""

    type: Literal["sphere"] = "sphere"
    centre: list[FiniteFloat] = Field(description="centre of the sphere (m)")
    radius: PositiveFloat = Field(description="radius (m)")
    spacing: PositiveFloat = Field(description="particle spacing dx (m)")
    arrangement: Literal["lattice", "shells"] = Field(
        "lattice", description="'lattice': the cubic lattice's cells within the radius (a "
        "staircase surface, flat facets at the poles); 'shells': round(radius / spacing) "
        "concentric shells of equal thickness, each with points spread evenly over it (a "
        "Fibonacci spiral) and its volume shared among them, so that the surface is round "
        "and the volume exact (a body whose curved surface meets another: contact)")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m)."""
        return [float(self.spacing)] * 3

    @model_validator(mode="after")
    def _not_empty(self) -> Sphere:
        if self.radius < math.sqrt(3.0) / 2.0 * self.spacing:
            raise ValueError(f"radius = {self.radius!r} holds no particle at spacing = "
                             f"{self.spacing!r} (needs radius >= sqrt(3)/2 spacing)")
        return self


class Cylinder(_Model):
    """A circular cylinder of particles (3D): layers of the :class:`Disk` lattice across
    ``axis``, ``round(length / spacing)`` of them (at least 1) at ``(k + 1/2) dx`` from the
    base, whose centre is ``centre``; the cylinder extends from the base in the positive
    direction of ``axis``.  Or, with ``arrangement = "rings"``, layers of concentric rings
    (:func:`impactsph.geometry.cylinder_particles`)."""

    type: Literal["cylinder"] = "cylinder"
    centre: list[FiniteFloat] = Field(description="centre of the base (m)")
    radius: PositiveFloat = Field(description="radius (m)")
    length: PositiveFloat = Field(description="length along the axis (m)")
    axis: Literal["x", "y", "z"] = Field("z", description="direction of the axis")
    spacing: PositiveFloat = Field(description="particle spacing dx (m)")
    arrangement: Literal["lattice", "rings"] = Field(
        "lattice", description="'lattice': layers of the square lattice's cells within the "
        "radius (a staircase surface; rows, columns and diagonals of particles across the "
        "section); 'rings': layers of round(length / spacing) equal thicknesses, each of "
        "round(radius / spacing) concentric rings of equal width, the points of each spread "
        "evenly round it and its area shared among them, so that the surface is round and "
        "the volume exact (a foot that spreads on a wall: docs/validation.md)")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m): ``spacing`` for the lattice; for the rings
        their width ``radius / round(radius / spacing)`` across the axis and the layers'
        thickness ``length / round(length / spacing)`` along it."""
        if self.arrangement == "lattice":
            return [float(self.spacing)] * 3
        from .geometry import whole_count  # the particles' own rounding

        across = self.radius / whole_count(self.radius, self.spacing)
        along = self.length / whole_count(self.length, self.spacing)
        return [float(along if a == self.axis else across) for a in "xyz"]

    @model_validator(mode="after")
    def _not_empty(self) -> Cylinder:
        if self.arrangement == "lattice" and not _lattice_holds_a_particle(self.radius,
                                                                           self.spacing):
            raise ValueError(f"radius = {self.radius!r} holds no particle at spacing = "
                             f"{self.spacing!r} (needs radius >= spacing / sqrt(2))")
        return self


class ParticleFile(_Model):
    """Particles read from a file: a CSV file with a header naming the columns ``x`` (``y``,
    ``z`` by dimension) and optionally ``volume``, or an NPZ file with the arrays ``position``
    (n, dim) and optionally ``volume`` (n,).  Each particle's mass is ``density * volume``, or
    ``density * spacing**dim`` without a volume; ``h = h_over_dx * spacing``.  A relative
    ``path`` in a case file is relative to the case file's directory (one given by ``--set``,
    to the current directory); the validated case holds the absolute path."""

    type: Literal["file"] = "file"
    path: str = Field(min_length=1, description="the CSV or NPZ file")
    spacing: PositiveFloat = Field(
        description="particle spacing dx (m): sets h, and the volume dx^dim of particles "
        "without one")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m): the one spacing, for every axis."""
        return [float(self.spacing)] * 3

    @field_validator("path")
    @classmethod
    def _absolute(cls, value: str) -> str:
        return os.path.abspath(os.path.expanduser(value))


GEOMETRY_TYPES = ("block", "disk", "ring", "cylinder", "sphere", "file")


def _geometry_type(value: Any) -> str | None:
    """The geometry's ``type`` (``block`` when left out); None for an unknown one."""
    if isinstance(value, dict):
        kind = value.get("type", "block")
    else:  # a model instance; anything else is reported as not a [geometry] table
        kind = getattr(value, "type", "block")
    return kind if isinstance(kind, str) and kind in GEOMETRY_TYPES else None


Geometry = Annotated[
    Annotated[Block, Tag("block")] | Annotated[Disk, Tag("disk")] | Annotated[Ring, Tag("ring")]
    | Annotated[Cylinder, Tag("cylinder")] | Annotated[Sphere, Tag("sphere")]
    | Annotated[ParticleFile, Tag("file")],
    Discriminator(_geometry_type, custom_error_type="geometry_type",
                  custom_error_message="Input should be " + ", ".join(
                      repr(t) for t in GEOMETRY_TYPES[:-1]) + f" or {GEOMETRY_TYPES[-1]!r}"),
]


class Region(_Model):
    """An axis-aligned box (m) selecting particles of a body."""

    origin: list[FiniteFloat]
    size: list[PositiveFloat]


class TipMass(_Model):
    """An extra mass spread evenly over the body's particles inside a region; those particles
    start at the velocity that conserves the momentum of the mass arriving at ``velocity``:
    ``V0 G / (G + M)``, M the particles' own mass (the Parkes cantilever, the paper's
    section 5.3)."""

    mass: PositiveFloat = Field(description="the extra mass G (kg)")
    depth: PositiveFloat | None = Field(
        None, description="in 2D, the out-of-plane thickness the mass is spread over (m): "
        "the model carries G / depth per unit depth")
    velocity: list[FiniteFloat] = Field(description="velocity V0 given to the mass (m/s)")
    region: Region
    carried_as: Literal["added_inertia", "particle_mass"] = Field(
        "added_inertia", description="how the particles carry G: \"added_inertia\" (a rigid "
        "mass moving with them: it enters their accelerations, momentum and kinetic energy, "
        "not their volumes m / rho) or \"particle_mass\" (the paper's: their masses grow by "
        "G, so their volumes and every kernel sum over them grow too; docs/validation.md, "
        "Example 3)")


class Driven(Region):
    """Particles of a body whose velocity is prescribed: a loading platen, the grips of a
    tension test (``impactsph.driven``).  Each component of ``velocity`` is a number or an
    expression of the time ``t`` (s), e.g. ``"5.0 * min(t / 1e-6, 1.0)"`` is not allowed
    (numexpr has no min) but ``"where(t < 1e-6, 5e6 * t, 5.0)"`` is: a ramp to 5 m/s."""

    name: str = Field(min_length=1, description="names its reaction force in history.csv")
    velocity: list[FiniteFloat | str] = Field(
        description="prescribed velocity (m/s): per axis a number or an expression of t (s)")


class Body(_Model):
    """A body: a material, a geometry and an initial velocity."""

    name: str = Field(min_length=1)
    material: str = Field(description="key of a [materials.NAME] table")
    geometry: Geometry = Field(description="the particles: a block, disk, ring, cylinder or "
                               "file")
    velocity: list[FiniteFloat | str] = Field(
        description="initial velocity (m/s): per axis a number, or an expression of x, y, z "
        "(m) evaluated at each particle (impactsph.initial), e.g. ['-1000 * y', '1000 * x']")
    clamped: Region | list[Region] | None = Field(
        None, description="particles inside (one region or several) are held at zero "
        "velocity; they take part in every sum")
    driven: list[Driven] = Field(
        default_factory=list, description="regions whose particles move at a prescribed "
        "velocity, their reaction force recorded")
    tip_mass: TipMass | None = None
    h_over_dx: PositiveFloat | None = Field(
        None, description="this body's smoothing length over its particle spacing; None: "
        "kernel.h_over_dx.  A pair of particles of different h uses their mean, so the sums "
        "stay symmetric (momentum and energy kept).  Measured (docs/stabilisation.md): a "
        "thick body that is squashed (a Taylor foot) converges with 1.6, a beam a few "
        "particles thick converges with 1.3 and not with 1.6")


class Wall(_Model):
    """A rigid plane wall, modelled by ghost particles: mirror images of the particles within
    the kernel's reach.  The wall pushes (compression only) and transmits no shear stress;
    ``slip = 'free'`` mirrors the normal velocity only, ``'no'`` mirrors the whole velocity
    (v_ghost = -v), so that the artificial viscosity also resists sliding along the wall."""

    type: Literal["wall"] = "wall"
    point: list[FiniteFloat] = Field(description="a point of the wall plane (m)")
    normal: list[FiniteFloat] = Field(description="normal pointing into the material")
    slip: Literal["free", "no"] = "free"
    friction: NonNegativeFloat = Field(
        0.0, description="Coulomb friction coefficient mu: a particle the wall pushes with "
        "f_n is slowed along it by mu f_n (impactsph.boundaries.friction_push); its work is "
        "booked as heat")


class Symmetry(_Model):
    """A symmetry plane: the model is the half on the side the normal points to, and the other
    half is its mirror image.  Modelled by mirror ghosts of the particles (and of the walls'
    ghosts) within the kernel's reach, which belong to their sources' bodies: they carry the
    whole stress (tension and shear too), the viscosity and the correction as the mirrored
    half would (docs/case-files.md).  Not a wall: no contact law, no penalty layer.  A half
    or quarter model equals the whole one when the whole one is symmetric (to round-off:
    ``tests/test_symmetry.py``)."""

    type: Literal["symmetry"] = "symmetry"
    point: list[FiniteFloat] = Field(description="a point of the plane (m)")
    normal: list[FiniteFloat] = Field(description="normal pointing into the modelled half")


#: a boundary's ``type``s (the tags of the :data:`Boundary` union)
BOUNDARY_TYPES = ("wall", "symmetry")


def _boundary_type(value: Any) -> str | None:
    """A boundary's ``type`` (``wall`` when left out); None for an unknown one."""
    kind = value.get("type", "wall") if isinstance(value, dict) else getattr(value, "type",
                                                                            "wall")
    return kind if kind in BOUNDARY_TYPES else None


Boundary = Annotated[
    Annotated[Wall, Tag("wall")] | Annotated[Symmetry, Tag("symmetry")],
    Discriminator(_boundary_type, custom_error_type="boundary_type",
                  custom_error_message="Input should be 'wall' or 'symmetry'"),
]


#: the largest smoothing length over h0 that ``kernel.max_stretch = "auto"`` gives a case whose
#: materials yield: 1.6 / 1.3, the kernel width that makes the plane-strain Taylor foot converge
#: over the paper's (docs/stabilisation.md, "A kernel that follows the stretch")
AUTO_MAX_STRETCH = 1.23

#: the narrowest kernel (h / dx) with which ``"auto"`` switches the stretch on: with AV (1, 1)
#: at 1.2 dx the stretch tears the cantilever at x2 (docs/validation.md, Example 3)
AUTO_STRETCH_MIN_H_OVER_DX = 1.3


class Kernel(_Model):
    """Smoothing kernel and length."""

    type: Literal["cubic_spline"] = "cubic_spline"
    h_over_dx: PositiveFloat = Field(
        1.3, description="smoothing length over particle spacing; 1.3 (the paper's examples' "
        "width): at 1.2 the cantilever's tip moves +40% from x1 to x2 with AV (1, 1), at 1.3 "
        "-0.4% (docs/stabilisation.md, 'Defaults')")
    max_stretch: Annotated[float, Field(ge=1.0, le=4.0)] | Literal["auto"] = Field(
        "auto", description="the most a particle's smoothing length grows with "
        "the local stretch: at each neighbour-list build h = h0 clamp(lambda, 1, max_stretch), "
        "lambda the largest principal stretch of the least-squares deformation gradient of "
        "the particle's neighbourhood since t = 0 (impactsph.physics.stretch), so that a "
        "kernel keeps its neighbours where a body spreads (a Taylor bar's foot) and keeps h0 "
        "where it barely deforms (a beam); 1 keeps h fixed; 'auto' (the default): "
        f"{AUTO_MAX_STRETCH} (1.6 / 1.3, measured on the Taylor bar and the cantilever, "
        "docs/stabilisation.md) where a material yields, none has a damage model, every "
        f"body's h_over_dx is at least {AUTO_STRETCH_MIN_H_OVER_DX}, the formulation is "
        "updated-Lagrangian in plane strain or 3D, without the artificial stress, on the CPU "
        "or on the GPU with the state there (compute.resident); else 1")


#: the hourglass coefficient zeta that ``"auto"`` gives a case whose materials do not yield
#: (measured on the clamped beam: docs/stabilisation.md)
AUTO_HOURGLASS = 2.0


#: the total-Lagrangian hourglass coefficient alpha (``tl_hourglass``; measured on the clamped
#: beam: docs/stabilisation.md, "Total-Lagrangian formulation")
TL_HOURGLASS = 10.0
#: the dashpot's damping ratio beside it (docs/stabilisation.md, "Total-Lagrangian formulation")
TL_HOURGLASS_DAMPING = 0.5
#: the factor k of the penalty contact between total-Lagrangian bodies: Hertz's law between
#: the particles' spheres (k = 1) is too soft where the bodies press at a sizeable share of
#: their bulk modulus; k = 4 meets Hertz's contact time between two spheres within 1% at
#: 10-20 spacings per radius and the colliding bars' 2 L / c within 0.4% (docs/stabilisation.md,
#: "Contact between total-Lagrangian bodies")
PENALTY_STIFFNESS = 4.0


class Stabilisation(_Model):
    """Remedies for the discretisation's own errors (docs/stabilisation.md).  ``"auto"`` (the
    default of ``gradient_correction`` and ``hourglass``) resolves, when the case is
    validated, to the measured choice: the kernel gradient correction of the velocity gradient
    and forces with the hourglass control at zeta = 2 when no material of the case yields (an
    elastic beam converges only with them), neither when one does (they raise the Taylor bar's
    plastic work by 25% at the paper's resolution, and the elastic hourglass spring makes a
    plastic bar rebound).  The paper's examples set ``"none"`` and 0: its scheme exactly."""

    gradient_correction: Literal["auto", "none", "velocity_gradient",
                                 "velocity_gradient_and_forces"] = Field(
        "auto", description="'velocity_gradient': the kernel gradient correction (Randles & "
        "Libersky 1996) of the velocity gradient, exact for linear velocity fields at free "
        "surfaces too; 'velocity_gradient_and_forces': also the stress forces, in the "
        "symmetric form of Bonet & Lok (1999) that keeps momentum and energy; 'none': the "
        "plain SPH gradient of eq 15 (the paper's); 'auto': 'velocity_gradient_and_forces' "
        "if no material yields, else 'none'")
    hourglass: NonNegativeFloat | Literal["auto"] = Field(
        "auto", description="coefficient zeta of the hourglass control: an elastic restoring "
        "acceleration zeta mu / rho times the (non-nested) Laplacian of the relative motion "
        "that the velocity gradient does not explain; 0 switches it off; 'auto': 2 if no "
        "material yields, else 0")
    artificial_stress: NonNegativeFloat = Field(
        0.0, description="coefficient epsilon of the artificial stress against the tensile "
        "instability (Monaghan 2000; Gray, Monaghan & Swift 2001): a repulsion -epsilon "
        "sigma'/rho^2 along each principal direction in tension, weighted by (W(r)/W(dx))^n; "
        "0.3 is their value for solids; it also softens the material in tension (a tensile "
        "wave 10% slower in 1D at 0.3: docs/stabilisation.md); 0 switches it off")
    tl_hourglass: NonNegativeFloat = Field(
        TL_HOURGLASS, description="coefficient alpha of the total-Lagrangian formulation's "
        "hourglass control (Ganzenmueller 2015): a penalty along each reference pair, alpha/2 "
        "E V0_i V0_j W_ij / |X_ij|^2 times the pair's error against the particles' "
        "deformation gradients, its work booked in their internal energy; 0 switches it off; "
        "used by formulation = 'total_lagrangian' only")
    tl_hourglass_damping: NonNegativeFloat = Field(
        TL_HOURGLASS_DAMPING, description="damping ratio zeta of a dashpot beside the "
        "total-Lagrangian hourglass penalty, on the rate of the same pair error (tau = 2 zeta "
        "/ omega, omega the particle's zig-zag frequency under the penalty): with 0.5 the time "
        "step may reach omega dt = 1.5, with 0 (Ganzenmueller's spring alone) 0.5, which "
        "takes 2.1-2.7 times the steps (docs/stabilisation.md); used by formulation = "
        "'total_lagrangian' only")
    artificial_stress_exponent: float = Field(
        4.0, gt=0.0, description="exponent n of the artificial stress's weight "
        "(W(r)/W(dx))^n (Gray et al. 2001 use 4)")
    artificial_stress_compensation: bool = Field(
        False, description="cancel the smooth part of the artificial stress's force: its "
        "pair weight becomes (W(r)/W(dx))^n - kappa, kappa = M_f / M of the initial lattice "
        "(impactsph.kernels.artificial_stress_moment), so that long tensile waves keep their "
        "speed while close pairs are still pushed apart (docs/stabilisation.md); needs "
        "artificial_stress > 0")

    @model_validator(mode="after")
    def _compensation_needs_the_artificial_stress(self) -> Stabilisation:
        if self.artificial_stress_compensation and self.artificial_stress == 0.0:
            raise ValueError("stabilisation.artificial_stress_compensation = true needs "
                             "stabilisation.artificial_stress > 0 (it compensates that term); "
                             "set artificial_stress (e.g. 0.3) or leave the compensation off")
        return self


class Contact(_Model):
    """What particles of different bodies, and particles and their wall ghosts, exchange
    (docs/modelling.md, "Contact between bodies"; docs/stabilisation.md)."""

    traction: Literal["pressure", "normal_stress"] = Field(
        "normal_stress", description="'pressure': the pair pushes with P_i/rho_i^2 + "
        "P_j/rho_j^2 (the paper's contact); 'normal_stress': with the compressive normal stress "
        "along the line of centres, deviatoric part included, so that a wall holds a body "
        "whose stress normal to it exceeds its pressure")
    wall_layer: float = Field(
        0.25, ge=0.0, lt=0.5, description="thickness, in particle spacings, of the rigid walls' "
        "penalty layer: a spring as stiff as the material (bulk modulus) and a dashpot that "
        "push a particle closer than this to a wall back off it, their work booked in its "
        "internal energy (impactsph.boundaries.layer_push); it holds a layer that thins as it "
        "spreads along the wall, which the ghosts alone let through; 0 switches it off. "
        "Updated-Lagrangian only: a total-Lagrangian body meets a wall through the penalty "
        "contact (penalty_stiffness, penalty_distance)")
    friction: float = Field(
        0.0, ge=0.0, description="Coulomb friction coefficient between bodies in contact: a "
        "pushing pair sliding past each other is slowed by mu times its push, the work booked "
        "as heat in the two particles (impactsph.physics.contact); 0 is frictionless. A "
        "wall's friction is the wall's own 'friction'")
    penalty_stiffness: PositiveFloat = Field(
        PENALTY_STIFFNESS, description="factor k on the penalty contact between "
        "total-Lagrangian bodies (impactsph.physics.penalty_contact): a pair of particles of "
        "different bodies closer than their contact diameter is pushed apart by Hertz's "
        "force 2/3 k K* d^(dim-1) (delta/d)^(3/2), K* the two bulk moduli in series, its "
        "work booked in their internal energies; 4 (chosen on Hertz's spheres and the "
        "colliding bars) is stiffer than Hertz's law between the particles (1); used by "
        "formulation = 'total_lagrangian' only, between bodies and against rigid walls (a "
        "particle pushed as by its mirror image)")
    penalty_distance: PositiveFloat = Field(
        1.0, description="contact diameter of the penalty contact between total-Lagrangian "
        "bodies, in particle spacings (m/rho0)^(1/dim): 1 puts the contact where the bodies' "
        "surfaces, half a spacing beyond their outermost particles, touch; used by "
        "formulation = 'total_lagrangian' only")


class Viscosity(_Model):
    """Artificial viscosity: the ``scheme`` is a registered viscosity scheme
    (:mod:`impactsph.models.viscosity`: ``av``, Monaghan's eqs 29-30; ``ac``, the acceleration
    correction of eqs 31-37) and the other fields are the schemes' parameters, added by
    :func:`schema` (alpha1, alpha2, epsilon; correction, energy_correction,
    correction_h_ratio)."""

    scheme: str = Field(
        "av", description="'av': Monaghan artificial viscosity with (alpha1, alpha2); 'ac': "
        "the Shaw-Reid acceleration correction, which always uses (1, 1) (alpha1 and alpha2 "
        "are then not used); or a registered scheme")


class Time(_Model):
    """Time stepping (Table 1, eq 26)."""

    end: PositiveFloat = Field(description="end time (s)")
    courant: float = Field(0.3, gt=0.0, le=1.0, description="Courant number cs of eq 26")
    integrator: Literal["midpoint", "ssp_rk3"] = Field(
        "midpoint", description="time integrator: 'midpoint', the predictor-corrector of Table "
        "1 (two rate evaluations a step), or 'ssp_rk3', the third-order strong-stability-"
        "preserving Runge-Kutta method (three a step; it does not amplify undamped "
        "oscillations, and costs the same at 1.5 times the Courant number)")
    energy_update: Literal["rate", "compatible"] = Field(
        "rate", description="how the specific energy is advanced: 'rate', with its rate at the "
        "step's evaluation (eq 28, the paper's), or 'compatible', with the pair forces' work at "
        "each particle's mean velocity over the step (Owen 2014), which keeps kinetic plus "
        "internal energy exactly against those forces; one more pair pass a step, midpoint "
        "integrator; on the GPU with the state on the device only")
    wave_speed: Literal["bar", "p_wave"] = Field(
        "bar", description="wave speed of eq 26 and of the viscosity: 'bar' sqrt(E/rho) as in "
        "the paper, or 'p_wave' sqrt((K + 4/3 mu)/rho)"
    )
    max_steps: int | None = Field(None, gt=0, description="stop after this many steps")
    neighbour_skin: NonNegativeFloat = Field(
        0.1, description="Verlet skin of the neighbour list, in units of the kernel support 2h"
    )


class Probe(_Model):
    """A particle whose velocity is recorded every step: the one of ``body`` nearest to
    ``position`` at t = 0."""

    name: str
    body: str
    position: list[FiniteFloat]


#: What a gauge can record (``output.gauges``' ``fields``); the columns of ``gauges.csv``
#: each gives are :func:`impactsph.gauges.field_columns`'.
GAUGE_FIELDS = ("position", "displacement", "velocity", "density", "pressure",
                "specific_energy", "deviatoric_stress", "von_mises_stress", "plastic_work",
                "material_state")
#: What a gauge records when its ``fields`` are not given: every field but the strength
#: models' state.
DEFAULT_GAUGE_FIELDS = GAUGE_FIELDS[:-1]


class Gauge(Probe):
    """A material point whose fields are recorded every step in ``gauges.csv``: the particle
    of ``body`` nearest to ``position`` at t = 0, followed as it moves (a probe that records
    more than the velocity)."""

    fields: list[Literal[GAUGE_FIELDS]] = Field(  # type: ignore[valid-type]
        default_factory=lambda: list(DEFAULT_GAUGE_FIELDS), min_length=1,
        description="what to record: " + ", ".join(GAUGE_FIELDS))


class Output(_Model):
    """What a run writes."""

    snapshot_times: list[NonNegativeFloat] = Field(
        default_factory=list, description="times (s) at which the particle state is stored"
    )
    history_every: int = Field(1, ge=1, description="write a history row every N steps")
    figures: bool = True
    probes: list[Probe] = Field(default_factory=list)
    gauges: list[Gauge] = Field(
        default_factory=list, description="material points whose fields are recorded every "
        "step in gauges.csv")
    reference_viscosity: Viscosity | None = Field(
        None, description="a run whose viscosity differs from this one also runs the case "
        "with it and overlays it in its figures (the bars: AV (0.3, 0.3), the paper's optimum)")
    vtk_interval: PositiveFloat | None = Field(
        None, description="write a ParaView (VTK) snapshot every this much simulated time (s), "
        "at the first step at or after each multiple, and at t = 0 and the end")
    vtk_format: Literal["binary", "ascii"] = Field(
        "binary", description="encoding of the VTK data arrays")
    checkpoint_interval: PositiveFloat | None = Field(
        None, description="write an HDF5 checkpoint every this much simulated time (s); "
        "'impactsph run CASE --restart FILE' continues from one")


class Compute(_Model):
    """Where and how the rate passes run."""

    device: Literal["cpu", "gpu"] = Field(
        "cpu", description="'gpu' runs the rate passes on an NVIDIA GPU (numba-cuda); where "
        "none is present the run falls back to the CPU and says so")
    threads: Annotated[int, Field(ge=1)] | Literal["auto"] = Field(
        "auto", description="CPU threads of the compiled passes: 'auto' samples about once a "
        "second how many cores other processes hold and runs on the cores left (at most "
        "numba's thread count at the start, NUMBA_NUM_THREADS unless set lower), and takes "
        "half of them where trials of a few blocks of steps time that faster (a small run), "
        "saying so in the log when the count changes; a number fixes it (capped at "
        "NUMBA_NUM_THREADS); the results do not depend on it (impactsph.threads)")
    resident: bool = Field(
        True, description="with device = 'gpu': keep the state on the GPU between steps (the "
        "whole step runs there: docs/gpu.md) where the case allows it; the log says when it "
        "does not and why. false: copy the state up and the rates back at every evaluation")
    particle_order: Literal["auto", "input", "cells"] = Field(
        "auto", description="how the particles are numbered: 'input' as the bodies place "
        "them (body by body, each geometry's own order); 'cells' each body's particles "
        "renumbered at t = 0 in the order of the neighbour list's cells (Z order), so that the "
        "passes' reads and writes by particle number walk memory as their neighbour loops do "
        "(0.80 of a 2D step's time at 1e6 particles, none at 1e5 nor in 3D: docs/case-files.md, "
        "'Particle order'); 'auto' (the default) 'cells' for a 2D updated-Lagrangian run of "
        "500,000 particles or more, else 'input'. Each particle's results are those of "
        "'input', renumbered, and a renumbered run's snapshots carry each particle's input "
        "number ('input_index')")
    record_precision: Literal["float64", "float32"] = Field(
        "float64", description="the numbers of the neighbour records the pair loops read "
        "(position, velocity, density, stress over density squared, ... of every particle, "
        "in the list's order): 'float32' nearly halves their memory and memory traffic (on a "
        "GPU, the pair kernel's bound); the state, the time integration, the outputs and "
        "every sum stay float64, and positions are kept in two float32 parts added in "
        "float64 (separations as exact as float64's); the other columns' rounding (about "
        "6e-8 of each value) and the arithmetic between two of them, done in float32, are "
        "what change (docs/gpu.md, 'Records in float32')")


class Case(_Model):
    """A complete simulation case."""

    name: str = Field(min_length=1)
    description: str = ""
    plugins: list[str] = Field(
        default_factory=list, description="Python modules (dotted names) or .py files "
        "(relative to the case file) imported before the case is validated: where models, "
        "problems or boundaries of your own are registered")
    dimension: Literal[1, 2, 3]
    two_dimensional: Literal["plane_strain", "plane_stress", "axisymmetric"] = Field(
        "plane_strain", description="what a 2D case models: 'plane_strain' (eps_zz = 0: a "
        "long body, the paper's choice), 'plane_stress' (sigma_zz = 0: a thin plate loaded "
        "in its plane, each particle's thickness changing) or 'axisymmetric' (a body of "
        "revolution about the y axis: x is the radius r >= 0, y the axis z; masses, energies "
        "and forces per radian; the axis is a symmetry plane, added if the case has none; "
        "docs/modelling.md)")
    formulation: Literal["updated_lagrangian", "total_lagrangian"] = Field(
        "updated_lagrangian", description="'updated_lagrangian': kernel and neighbours of the "
        "current configuration (the paper's SPH); 'total_lagrangian': kernel and neighbours of "
        "the configuration at t = 0, deformation gradient and first Piola-Kirchhoff stress, "
        "for a single body that does not fragment (docs/stabilisation.md)")
    analysis: str = Field(
        "none", description="problem-specific analysis and figures: 'none' or the name of a "
        "registered problem (impactsph.problems: 'bars', 'taylor', 'cantilever', ...)"
    )
    materials: dict[str, Material] = Field(min_length=1)
    bodies: list[Body] = Field(min_length=1)
    boundaries: list[Boundary] = Field(default_factory=list)
    kernel: Kernel = Field(default_factory=Kernel)
    stabilisation: Stabilisation = Field(default_factory=Stabilisation)
    contact: Contact = Field(default_factory=Contact)
    viscosity: Viscosity = Field(default_factory=Viscosity)
    time: Time
    output: Output = Field(default_factory=Output)
    compute: Compute = Field(default_factory=Compute)

    @field_validator("analysis")
    @classmethod
    def _registered_problem(cls, value: str) -> str:
        from .problems.registry import problem_names  # at use: it registers the problems

        if value not in problem_names():
            *rest, last = map(repr, problem_names())
            raise ValueError(f"Input should be {', '.join(rest) + ' or ' if rest else ''}{last} "
                             f"(the registered problems)")
        return value

    def h_over_dx_of(self, b: int) -> float:
        """Body ``b``'s smoothing length over its spacing: its own ``h_over_dx``, else the
        kernel's."""
        own = self.bodies[b].h_over_dx
        return float(self.kernel.h_over_dx if own is None else own)

    @model_validator(mode="after")
    def _consistent(self) -> Case:
        d = self.dimension
        epsilon = self.stabilisation.artificial_stress
        for b, body in enumerate(self.bodies):
            if epsilon > 0.0 and body.h_over_dx not in (None, self.kernel.h_over_dx):
                raise ValueError(
                    f"bodies.{b}.h_over_dx = {body.h_over_dx!r} with "
                    f"stabilisation.artificial_stress = {epsilon!r}: the artificial stress's "
                    f"reference spacing (dx / h = 1 / kernel.h_over_dx = "
                    f"{self.kernel.h_over_dx!r}) is one number for the run; give the body "
                    f"kernel.h_over_dx or switch the artificial stress off")
        stretch = self.kernel.max_stretch
        if stretch != "auto" and stretch > 1.0:
            if epsilon > 0.0:
                raise ValueError(
                    f"kernel.max_stretch = {stretch!r} with stabilisation.artificial_stress = "
                    f"{epsilon!r}: the artificial stress's reference spacing is one number for "
                    f"the run; set kernel.max_stretch = 1 or switch the artificial stress off")
            if self.formulation == "total_lagrangian":
                raise ValueError(f"kernel.max_stretch = {stretch!r} is not available with "
                                 f"formulation = 'total_lagrangian' (its kernel is the "
                                 f"reference configuration's); 1")
        if self.two_dimensional != "plane_strain":
            if d != 2:
                raise ValueError(f"two_dimensional = {self.two_dimensional!r} is for dimension "
                                 f"= 2 (the case has dimension = {d})")
            if self.formulation == "total_lagrangian":
                raise ValueError(f"two_dimensional = {self.two_dimensional!r} is not available "
                                 f"with formulation = 'total_lagrangian' (its passes are "
                                 f"plane strain)")
            if self.two_dimensional == "axisymmetric":
                self._axisymmetric_limits()
        names = set()
        for k, body in enumerate(self.bodies):
            where = f"bodies.{k}"
            if body.name in names:
                raise ValueError(f"{where}.name = {body.name!r} is used by two bodies")
            names.add(body.name)
            if body.material not in self.materials:
                raise ValueError(f"{where}.material = {body.material!r} is not one of "
                                 f"{sorted(self.materials)}")
            g = body.geometry
            if isinstance(g, Block):
                for field in ("origin", "size"):
                    if len(getattr(g, field)) != d:
                        raise ValueError(f"{where}.geometry.{field} has "
                                         f"{_components(len(getattr(g, field)))}; "
                                         f"dimension = {d} needs {d}")
            elif isinstance(g, Disk | Ring | Cylinder | Sphere):
                needs = 3 if isinstance(g, Cylinder | Sphere) else 2
                if d != needs:
                    raise ValueError(f"{where}.geometry: type = {g.type!r} is for dimension = "
                                     f"{needs} only")
                if len(g.centre) != d:
                    raise ValueError(f"{where}.geometry.centre has "
                                     f"{_components(len(g.centre))}; dimension = {d} needs {d}")
            for a, component in enumerate(body.velocity):
                if isinstance(component, str):
                    from .initial import check_expression

                    why = check_expression(component, d)
                    if why:
                        raise ValueError(f"{where}.velocity.{a} = {component!r}: {why}")
            if len(body.velocity) != d:
                raise ValueError(f"{where}.velocity has {_components(len(body.velocity))}; "
                                 f"dimension = {d} needs {d}")
            if isinstance(g, Block):
                if isinstance(g.spacing, list) and len(g.spacing) != d:
                    raise ValueError(f"{where}.geometry.spacing needs 1 or {d} values")
                if g.count is not None and len(g.count) != d:
                    raise ValueError(f"{where}.geometry.count needs {d} values")
            clamps = body.clamped if isinstance(body.clamped, list) else [body.clamped]
            regions = [(f"clamped.{k}" if isinstance(body.clamped, list) else "clamped", c)
                       for k, c in enumerate(clamps)]
            for k, drive in enumerate(body.driven):
                regions.append((f"driven.{k}", drive))
                if len(drive.velocity) != d:
                    raise ValueError(f"{where}.driven.{k}.velocity has "
                                     f"{_components(len(drive.velocity))}; dimension = {d} "
                                     f"needs {d}")
                for a, component in enumerate(drive.velocity):
                    if isinstance(component, str):
                        from .initial import check_expression

                        why = check_expression(component, d, names=("t",))
                        if why:
                            raise ValueError(f"{where}.driven.{k}.velocity.{a} = "
                                             f"{component!r}: {why}")
            if body.tip_mass is not None:
                regions.append(("tip_mass.region", body.tip_mass.region))
                if len(body.tip_mass.velocity) != d:
                    raise ValueError(f"{where}.tip_mass.velocity needs {d} components")
                if d == 2 and body.tip_mass.depth is None:
                    raise ValueError(f"{where}.tip_mass.depth is needed in 2D (the mass is "
                                     f"spread per unit depth)")
            for name, region in regions:
                if region is not None and (len(region.origin) != d or len(region.size) != d):
                    raise ValueError(f"{where}.{name} needs origin and size of {d} components")
        for k, wall in enumerate(self.boundaries):
            if len(wall.point) != d or len(wall.normal) != d:
                raise ValueError(f"boundaries.{k}: point and normal need {d} components")
            if sum(c * c for c in wall.normal) == 0:
                raise ValueError(f"boundaries.{k}.normal = {wall.normal}: must not be zero")
        # the analyses measure bodies by their lattices (the bars by the blocks' lengths):
        # what the problem needs of the leading bodies (impactsph.problems.GeometryNeeds)
        from .problems.registry import get_problem

        needs = get_problem(self.analysis).geometry_needs
        if needs is not None:
            for k, body in enumerate(self.bodies[: needs.bodies]):
                if body.geometry.type not in needs.types:
                    raise ValueError(f"bodies.{k}.geometry: analysis = {self.analysis!r} "
                                     f"needs type = {' or '.join(map(repr, needs.types))}, not "
                                     f"{body.geometry.type!r}")
            if len(self.bodies) < needs.bodies:
                raise ValueError(f"bodies: analysis = {self.analysis!r} needs {needs.bodies} "
                                 f"bodies, the case has {len(self.bodies)}")
        for name, mat in self.materials.items():
            allowed = STRENGTH[mat.model].dimensions
            if d not in allowed:
                raise ValueError(f"materials.{name}.model = {mat.model!r} is for dimension = "
                                 f"{' or '.join(map(str, allowed))} only")
        for kind, points in (("probes", self.output.probes), ("gauges", self.output.gauges)):
            seen: set[str] = set()
            for k, probe in enumerate(points):
                if probe.body not in names:
                    raise ValueError(f"output.{kind}.{k}.body = {probe.body!r} is not a body "
                                     f"name")
                if len(probe.position) != d:
                    raise ValueError(f"output.{kind}.{k}.position needs {d} components")
                if kind == "gauges" and probe.name in seen:
                    raise ValueError(f"output.gauges.{k}.name = {probe.name!r} is used by two "
                                     f"gauges")
                seen.add(probe.name)
        if self.formulation == "total_lagrangian":
            self._total_lagrangian_limits()
        if self.time.integrator == "ssp_rk3" and self.viscosity.scheme == "ac_optimised":
            raise ValueError("time.integrator = 'ssp_rk3' with viscosity.scheme = "
                             "'ac_optimised': that scheme optimises each factor over the time "
                             "to the next rate evaluation, which the three-stage step's "
                             "evaluations (at t, t + dt, t + dt/2) do not give; use "
                             "time.integrator = 'midpoint'")
        if self.time.energy_update == "compatible":
            if self.time.integrator != "midpoint":
                raise ValueError(f"time.energy_update = 'compatible' with time.integrator = "
                                 f"{self.time.integrator!r}: the update needs the step's "
                                 f"forces from one evaluation; use time.integrator = "
                                 f"'midpoint'")
            if self.formulation == "total_lagrangian":
                raise ValueError("time.energy_update = 'compatible' with formulation = "
                                 "'total_lagrangian': the update is built for the "
                                 "updated-Lagrangian pair pass; use energy_update = 'rate'")
        self._resolve_stabilisation()
        self._resolve_stretch()
        return self

    def _axisymmetric_limits(self) -> None:
        """Axisymmetry: the axis x = 0 is a symmetry plane (added when missing); no other
        symmetry plane across r, no wall parallel to the axis, no tip mass (its depth is a
        plane model's), and none of the remedies whose sums are the plane form's."""
        axis = False
        for k, boundary in enumerate(self.boundaries):
            if boundary.normal[0] == 0.0:  # normal to the axis: any kind
                continue
            if boundary.type == "symmetry":
                if boundary.normal[1] != 0.0 or boundary.point[0] != 0.0 \
                        or boundary.normal[0] < 0:
                    raise ValueError(f"boundaries.{k}: in axisymmetry a symmetry plane across r "
                                     f"is the axis only (point x = 0, normal [1, 0])")
                axis = True
            elif boundary.type == "wall":
                raise ValueError(f"boundaries.{k}: in axisymmetry a wall is normal to the "
                                 f"axis (normal [0, 1] or [0, -1]), not {list(boundary.normal)} "
                                 f"(a wall parallel to it is not validated: docs/modelling.md)")
        if not axis:
            self.boundaries.append(Symmetry(point=[0.0, 0.0], normal=[1.0, 0.0]))
        for k, body in enumerate(self.bodies):
            if body.tip_mass is not None:
                raise ValueError(f"bodies.{k}.tip_mass is not available with two_dimensional = "
                                 f"'axisymmetric' (its depth is a plane model's)")
        # the remedies whose sums are mass-weighted in the plane form (docs/modelling.md)
        axi = "with two_dimensional = 'axisymmetric'"
        stab = self.stabilisation
        if stab.gradient_correction == "velocity_gradient_and_forces":
            raise ValueError(f"stabilisation.gradient_correction = 'velocity_gradient_and_"
                             f"forces' is not available {axi}; 'velocity_gradient' or 'none'")
        if stab.hourglass != "auto" and stab.hourglass > 0.0:
            raise ValueError(f"stabilisation.hourglass = {stab.hourglass!r} is not available "
                             f"{axi}; 0")
        if self.contact.friction > 0.0:
            raise ValueError(f"contact.friction = {self.contact.friction!r} (between bodies) "
                             f"is not available {axi}; 0 (walls may have friction)")

    def _total_lagrangian_limits(self) -> None:
        """Refuse what the total-Lagrangian formulation does not do, in one line each."""
        tl = "with formulation = 'total_lagrangian'"
        stab = self.stabilisation
        if len(self.bodies) > 1 and self.contact.friction > 0.0:
            raise ValueError(f"contact.friction = {self.contact.friction!r} is not available "
                             f"{tl} (its bodies meet through the frictionless penalty "
                             f"contact); 0")
        if self.compute.device != "cpu":
            raise ValueError(f"compute.device = {self.compute.device!r}: the total-Lagrangian "
                             f"passes run on the CPU only")
        if self.viscosity.scheme != "av":
            raise ValueError(f"viscosity.scheme = {self.viscosity.scheme!r} is not available "
                             f"{tl} (use 'av')")
        if stab.gradient_correction not in ("auto", "none"):
            raise ValueError(f"stabilisation.gradient_correction = "
                             f"{stab.gradient_correction!r} is an updated-Lagrangian option "
                             f"(the total-Lagrangian gradient is always corrected)")
        if stab.hourglass not in ("auto", 0.0):
            raise ValueError(f"stabilisation.hourglass = {stab.hourglass!r} is an "
                             f"updated-Lagrangian option ({tl} use stabilisation.tl_hourglass)")
        if stab.artificial_stress > 0.0:
            raise ValueError(f"stabilisation.artificial_stress = {stab.artificial_stress!r} is "
                             f"an updated-Lagrangian option (a total-Lagrangian body has no "
                             f"tensile instability)")
        for k, boundary in enumerate(self.boundaries):
            if boundary.type == "symmetry":
                raise ValueError(f"boundaries.{k}: type = 'symmetry' is not available {tl} "
                                 f"(symmetry planes are mirror ghosts of the updated-Lagrangian "
                                 f"passes)")
            if boundary.friction > 0.0:
                raise ValueError(f"boundaries.{k}.friction = {boundary.friction!r} is not "
                                 f"available {tl} (wall friction acts on the ghosts' push)")

    def _resolve_stabilisation(self) -> None:
        """Replace the ``"auto"`` of ``[stabilisation]`` by the measured choice (see
        :class:`Stabilisation`), so that the case recorded with a run says what ran."""
        stab = self.stabilisation
        if self.formulation == "total_lagrangian":  # the UL remedies do not apply
            stab.gradient_correction = "none"
            stab.hourglass = 0.0
            return
        elastic = all(STRENGTH[m.model].return_map is None for m in self.materials.values())
        axisymmetric = self.two_dimensional == "axisymmetric"  # neither corrected forces nor
        corrected = "velocity_gradient" if axisymmetric else "velocity_gradient_and_forces"
        if stab.gradient_correction == "auto":  # hourglass control there (docs/modelling.md)
            stab.gradient_correction = corrected if elastic else "none"
        if stab.hourglass == "auto":
            stab.hourglass = AUTO_HOURGLASS if elastic and not axisymmetric else 0.0

    def _resolve_stretch(self) -> None:
        """Replace ``kernel.max_stretch = "auto"`` by the measured choice (see :class:`Kernel`):
        the stretch where it was measured to make the answers converge (a plastic Taylor bar
        and cantilever, docs/stabilisation.md), a fixed kernel everywhere else."""
        kernel = self.kernel
        if kernel.max_stretch != "auto":
            return
        yields = any(STRENGTH[m.model].return_map is not None
                     for m in self.materials.values())
        damage = any(m.damage != "none" for m in self.materials.values())
        wide = all(self.h_over_dx_of(b) >= AUTO_STRETCH_MIN_H_OVER_DX - 1e-12
                   for b in range(len(self.bodies)))
        on = (yields and not damage and wide and self.formulation != "total_lagrangian"
              and self.two_dimensional != "axisymmetric"
              and self.stabilisation.artificial_stress == 0.0
              # (the GPU with its state on the device sets it too, since 2026-12-07)
              and (self.compute.device == "cpu" or self.compute.resident))
        kernel.max_stretch = AUTO_MAX_STRETCH if on else 1.0


def model_keys(model: Any) -> tuple[str, ...]:
    """The material table's keys that hold a registered model's parameters: its parameters'
    fields where it is registered ``flat`` (``yield_stress`` of ``elastic_plastic``), else
    one sub-table named after it (``[materials.X.mie_gruneisen]``); none without
    parameters."""
    if model.parameters is None:
        return ()
    if getattr(model, "flat", False):
        return tuple(model.parameters.model_fields)
    return (model.name,)


def _optional(info: Any) -> tuple[Any, Any]:
    """A field of a model's parameters as an optional field of the enclosing table (required
    only when that model is selected, which the table's validator checks)."""
    annotation = Annotated[(info.annotation, *info.metadata)] if info.metadata else \
        info.annotation
    return annotation | None, Field(None, description=info.description)


def _same_field(a: Any, b: Any) -> bool:
    """Whether two pydantic fields take the same values with the same default."""
    return (a.annotation, repr(a.metadata), a.default) == (b.annotation, repr(b.metadata),
                                                           b.default)


def _union_fields(tables: list[tuple[str, type[_Model]]], where: str) -> dict[str, Any]:
    """The fields of several models' parameters, merged into one table; a name declared by
    two models must mean the same in both."""
    fields: dict[str, Any] = {}
    owner: dict[str, str] = {}
    for name, params in tables:
        for field, info in params.model_fields.items():
            if field in fields and not _same_field(fields[field][1], info):
                raise ValueError(f"{where}: {name!r} and {owner[field]!r} both declare the "
                                 f"field {field!r}, differently")
            if field not in fields:
                fields[field], owner[field] = (info.annotation, info), name
    return {f: (Annotated[(info.annotation, *info.metadata)] if info.metadata
                else info.annotation, info) for f, (_, info) in fields.items()}


def check_model_fields() -> None:
    """Raise :class:`ValueError` where two registered models declare one key of a case table
    differently: a field of the ``[viscosity]`` table; a key of the material table (a flat
    model's field, another model's sub-table named after it, or one of the table's own
    fields).  Run after each registration (:data:`impactsph.models.registry.REGISTRY_CHECKS`),
    which is undone where it raises: a plugin's ``yield_stress`` of another range had taken
    the place of ``elastic_plastic``'s in the schema, without a word."""
    _union_fields([(v.name, v.parameters) for v in VISCOSITY if v.parameters is not None],
                  "viscosity schemes")
    own = set(Material.model_fields)
    keys: dict[str, tuple[str, Any]] = {}  # key: (its first model, its field where flat)
    for registry in (DAMAGE, EOS, STRENGTH):
        for model in registry:
            flat = getattr(model, "flat", False)
            for key in model_keys(model):
                owner = f"{registry.kind} {model.name!r}"
                info = model.parameters.model_fields[key] if flat else None
                what = f"field {key!r}" if flat else f"table [{key}]"
                if key in own:
                    raise ValueError(f"{owner}: its {what} is the material table's own "
                                     f"field {key!r}; choose another name")
                if key in keys:
                    first, first_info = keys[key]
                    if info is None or first_info is None or not _same_field(info, first_info):
                        raise ValueError(f"{owner} and {first} both declare the material "
                                         f"table's key {key!r}, differently; choose another "
                                         f"name")
                else:
                    keys[key] = (owner, info)


_registry.REGISTRY_CHECKS.append(check_model_fields)


def _names(registry: Any) -> Any:
    return Literal[registry.names()]


_SCHEMA: dict[int, Any] = {}


def schema() -> Any:
    """The case schema for the models registered now: a namespace with the classes
    ``Material``, ``Viscosity``, ``Output`` and ``Case`` (subclasses of this module's
    classes, with the registered models' names and parameters added).  Rebuilt when a model
    is registered (:func:`impactsph.models.register`)."""
    from types import SimpleNamespace

    from pydantic import create_model

    version = _registry.version()
    if version in _SCHEMA:
        return _SCHEMA[version]
    material_fields: dict[str, Any] = {"model": (_names(STRENGTH), Material.model_fields[
        "model"]), "eos": (_names(EOS), Material.model_fields["eos"]),
        "damage": (_names(DAMAGE), Material.model_fields["damage"])}
    for registry in (DAMAGE, EOS, STRENGTH):
        for model in registry:
            for key in model_keys(model):
                material_fields[key] = (
                    _optional(model.parameters.model_fields[key])
                    if getattr(model, "flat", False)
                    else (model.parameters | None, Field(None)))
    material = create_model("Material", __base__=Material, **material_fields)
    viscosity = create_model(
        "Viscosity", __base__=Viscosity,
        scheme=(_names(VISCOSITY), Viscosity.model_fields["scheme"]),
        **_union_fields([(v.name, v.parameters) for v in VISCOSITY if v.parameters is not None],
                        "viscosity schemes"))
    output = create_model("Output", __base__=Output, reference_viscosity=(
        viscosity | None, Output.model_fields["reference_viscosity"]))
    case = create_model(
        "Case", __base__=Case,
        materials=(dict[str, material], Case.model_fields["materials"]),
        viscosity=(viscosity, Field(default_factory=viscosity)),
        output=(output, Field(default_factory=output)))
    _SCHEMA.clear()
    _SCHEMA[version] = SimpleNamespace(Material=material, Viscosity=viscosity, Output=output,
                                       Case=case)
    return _SCHEMA[version]
