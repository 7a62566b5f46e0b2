"""Case files: the schema, validated by pydantic, and the loading of TOML files.

A case is a TOML file (see ``examples/`` and ``docs/case-files.md``); every field has SI
units.  Loading validates the whole case before any computation: an unknown key, a value of the
wrong type or out of range raises :class:`CaseError` whose message is one line naming the field,
the value and what is allowed.
"""

from __future__ import annotations

import copy
import os
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
    model_validator,
)

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


class CaseError(ValueError):
    """A case that cannot be run; the message is one line for the user."""


class _Model(BaseModel):
    # strict: a string or a boolean is never taken for a number (TOML has real types)
    model_config = ConfigDict(extra="forbid", validate_default=True, strict=True)


class MieGruneisen(_Model):
    """Mie-Gruneisen EOS parameters (eqs 7-12)."""

    sound_speed: PositiveFloat = Field(description="bulk sound speed C of eq 10 (m/s)")
    slope: NonNegativeFloat = Field(description="Hugoniot slope S of eqs 11-12")
    gamma: NonNegativeFloat = Field(description="Gruneisen parameter Gamma of eq 7")


class Material(_Model):
    """A material: elastic constants, equation of state, strength."""

    model: Literal["bar", "elastic", "elastic_plastic"] = Field(
        description="'bar': 1D uniaxial stress with modulus E; 'elastic'; 'elastic_plastic' "
        "(von Mises perfect plasticity)"
    )
    density: PositiveFloat = Field(description="reference density rho0 (kg/m^3)")
    youngs_modulus: PositiveFloat = Field(description="Young's modulus E (Pa)")
    poisson_ratio: float = Field(0.3, gt=-1.0, lt=0.5, description="Poisson's ratio, in (-1, 0.5)")
    shear_modulus: PositiveFloat | None = Field(
        None, description="shear modulus mu (Pa); default E / (2 (1 + nu))"
    )
    eos: Literal["linear", "mie_gruneisen"] = Field(
        "linear", description="'linear' (eq 6, K = E / (3 (1 - 2 nu))) or 'mie_gruneisen'"
    )
    mie_gruneisen: MieGruneisen | None = None
    yield_stress: PositiveFloat | None = Field(None, description="von Mises yield stress (Pa)")

    @model_validator(mode="after")
    def _consistent(self) -> Material:
        if self.eos == "mie_gruneisen" and self.mie_gruneisen is None:
            raise ValueError("eos = 'mie_gruneisen' needs a [mie_gruneisen] table")
        if self.model == "elastic_plastic" and self.yield_stress is None:
            raise ValueError("model = 'elastic_plastic' needs yield_stress (Pa)")
        if self.model == "bar" and self.eos != "linear":
            raise ValueError("model = 'bar' takes eos = 'linear' only")
        return self


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


class Cylinder(_Model):
    """A circular cylinder of particles (3D): layers of the :class:`Disk` lattice across
    ``axis``, ``round(length / spacing)`` of them (at least 1) at ``(k + 1/2) dx`` from the
    base, whose centre is ``centre``; the cylinder extends from the base in the positive
    direction of ``axis``."""

    type: Literal["cylinder"] = "cylinder"
    centre: list[FiniteFloat] = Field(description="centre of the base (m)")
    radius: PositiveFloat = Field(description="radius (m)")
    length: PositiveFloat = Field(description="length along the axis (m)")
    axis: Literal["x", "y", "z"] = Field("z", description="direction of the axis")
    spacing: PositiveFloat = Field(description="particle spacing dx (m)")

    def spacings(self) -> list[float]:
        """Particle spacing along each axis (m)."""
        return [float(self.spacing)] * 3

    @model_validator(mode="after")
    def _not_empty(self) -> Cylinder:
        if not _lattice_holds_a_particle(self.radius, self.spacing):
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

    @field_validator("path")
    @classmethod
    def _absolute(cls, value: str) -> str:
        return os.path.abspath(os.path.expanduser(value))


GEOMETRY_TYPES = ("block", "disk", "cylinder", "file")


def _geometry_type(value: Any) -> str | None:
    """The geometry's ``type`` (``block`` when left out); None for an unknown one."""
    if isinstance(value, dict):
        kind = value.get("type", "block")
    else:  # a model instance; anything else is reported as not a [geometry] table
        kind = getattr(value, "type", "block")
    return kind if isinstance(kind, str) and kind in GEOMETRY_TYPES else None


Geometry = Annotated[
    Annotated[Block, Tag("block")] | Annotated[Disk, Tag("disk")]
    | Annotated[Cylinder, Tag("cylinder")] | Annotated[ParticleFile, Tag("file")],
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
    ``V0 G / (G + M)``, M the particles' own mass (the Parkes cantilever, NOTES 10)."""

    mass: PositiveFloat = Field(description="the extra mass G (kg)")
    depth: PositiveFloat | None = Field(
        None, description="in 2D, the out-of-plane thickness the mass is spread over (m): "
        "the model carries G / depth per unit depth")
    velocity: list[FiniteFloat] = Field(description="velocity V0 given to the mass (m/s)")
    region: Region


class Body(_Model):
    """A body: a material, a geometry and an initial velocity."""

    name: str = Field(min_length=1)
    material: str = Field(description="key of a [materials.NAME] table")
    geometry: Geometry = Field(description="the particles: a block, disk, cylinder or file")
    velocity: list[FiniteFloat] = Field(description="initial velocity (m/s)")
    clamped: Region | None = Field(
        None, description="particles inside are held at zero velocity; they take part in "
        "every sum")
    tip_mass: TipMass | None = None


class Wall(_Model):
    """A rigid plane wall, modelled by ghost particles: mirror images of the particles within
    the kernel's reach.  The wall pushes (compression only) and transmits no shear stress;
    ``slip = 'free'`` mirrors the normal velocity only, ``'no'`` mirrors the whole velocity
    (v_ghost = -v), so that the artificial viscosity also resists sliding along the wall."""

    type: Literal["wall"] = "wall"
    point: list[FiniteFloat] = Field(description="a point of the wall plane (m)")
    normal: list[FiniteFloat] = Field(description="normal pointing into the material")
    slip: Literal["free", "no"] = "free"


class Kernel(_Model):
    """Smoothing kernel and length."""

    type: Literal["cubic_spline"] = "cubic_spline"
    h_over_dx: PositiveFloat = Field(1.2, description="smoothing length over particle spacing")


class Viscosity(_Model):
    """Artificial viscosity (eqs 29-30) and its acceleration correction (eqs 31-37)."""

    scheme: Literal["av", "ac"] = Field(
        "av", description="'av': Monaghan artificial viscosity with (alpha1, alpha2); 'ac': "
        "the Shaw-Reid acceleration correction, which always uses (1, 1) (alpha1 and alpha2 "
        "are then not used)")
    alpha1: NonNegativeFloat = Field(1.0, description="linear coefficient alpha1 of eq 29")
    alpha2: NonNegativeFloat = Field(1.0, description="quadratic coefficient alpha2 of eq 29")
    epsilon: PositiveFloat = Field(0.01, description="epsilon of eq 30")
    correction: Literal["volume_weighted", "shepard", "neighbours_only"] = Field(
        "neighbours_only", description="AC reading of eq 34 (NOTES 8 a, b, c); see "
        "docs/acceleration-correction.md")
    energy_correction: Literal["work", "paper", "none"] = Field(
        "work", description="AC energy term: 'work' books the correction's work exactly, "
        "'paper' is eq 37 with its typo mended, 'none' adds nothing")
    correction_h_ratio: float = Field(
        0.5, gt=0.0, le=1.0, description="h_c / h of the correction kernel (section 4.1: 1/2)")


class Time(_Model):
    """Time stepping (Table 1, eq 26)."""

    end: PositiveFloat = Field(description="end time (s)")
    courant: float = Field(0.3, gt=0.0, le=1.0, description="Courant number cs of eq 26")
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


class Output(_Model):
    """What a run writes."""

    snapshot_times: list[NonNegativeFloat] = Field(
        default_factory=list, description="times (s) at which the particle state is stored"
    )
    history_every: int = Field(1, ge=1, description="write a history row every N steps")
    figures: bool = True
    probes: list[Probe] = Field(default_factory=list)
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


class Case(_Model):
    """A complete simulation case."""

    name: str = Field(min_length=1)
    description: str = ""
    dimension: Literal[1, 2, 3]
    analysis: Literal["none", "bars", "taylor", "cantilever"] = Field(
        "none", description="problem-specific analysis and figures"
    )
    materials: dict[str, Material] = Field(min_length=1)
    bodies: list[Body] = Field(min_length=1)
    boundaries: list[Wall] = Field(default_factory=list)
    kernel: Kernel = Field(default_factory=Kernel)
    viscosity: Viscosity = Field(default_factory=Viscosity)
    time: Time
    output: Output = Field(default_factory=Output)
    compute: Compute = Field(default_factory=Compute)

    @model_validator(mode="after")
    def _consistent(self) -> Case:
        d = self.dimension
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
                                         f"{len(getattr(g, field))} components; "
                                         f"dimension = {d} needs {d}")
            elif isinstance(g, Disk | Cylinder):
                needs = 2 if isinstance(g, Disk) else 3
                if d != needs:
                    raise ValueError(f"{where}.geometry: type = {g.type!r} is for dimension = "
                                     f"{needs} only")
                if len(g.centre) != d:
                    raise ValueError(f"{where}.geometry.centre has {len(g.centre)} components; "
                                     f"dimension = {d} needs {d}")
            if len(body.velocity) != d:
                raise ValueError(f"{where}.velocity has {len(body.velocity)} components; "
                                 f"dimension = {d} needs {d}")
            if isinstance(g, Block):
                if isinstance(g.spacing, list) and len(g.spacing) != d:
                    raise ValueError(f"{where}.geometry.spacing needs 1 or {d} values")
                if g.count is not None and len(g.count) != d:
                    raise ValueError(f"{where}.geometry.count needs {d} values")
            regions = [("clamped", body.clamped)]
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
        # the analyses measure bodies by their lattices: the bars by the blocks' lengths
        needs = {"bars": (2, ("block",)), "taylor": (1, ("block", "disk", "cylinder")),
                 "cantilever": (1, ("block", "disk", "cylinder"))}.get(self.analysis)
        if needs is not None:
            for k, body in enumerate(self.bodies[: needs[0]]):
                if body.geometry.type not in needs[1]:
                    raise ValueError(f"bodies.{k}.geometry: analysis = {self.analysis!r} "
                                     f"needs type = {' or '.join(map(repr, needs[1]))}, not "
                                     f"{body.geometry.type!r}")
        for name, mat in self.materials.items():
            if mat.model == "bar" and d != 1:
                raise ValueError(f"materials.{name}.model = 'bar' is for dimension = 1 only")
        for k, probe in enumerate(self.output.probes):
            if probe.body not in names:
                raise ValueError(f"output.probes.{k}.body = {probe.body!r} is not a body name")
            if len(probe.position) != d:
                raise ValueError(f"output.probes.{k}.position needs {d} components")
        return self


BUILTIN_CASES = ("bars", "taylor", "cantilever")


def builtin_case_path(name: str) -> Path:
    """Path of a case shipped with the package."""
    return Path(str(resources.files("impactsph") / "cases" / f"{name}.toml"))


def resolve_paths(data: dict[str, Any], directory: Path) -> dict[str, Any]:
    """Make the relative ``path`` of every ``type = "file"`` geometry in a case dict relative to
    ``directory`` (in place; entries that are not well formed are left for validation)."""
    bodies = data.get("bodies") if isinstance(data, dict) else None
    for body in bodies if isinstance(bodies, list) else []:
        geometry = body.get("geometry") if isinstance(body, dict) else None
        if not isinstance(geometry, dict) or geometry.get("type") != "file":
            continue
        path = geometry.get("path")
        if isinstance(path, str) and path and not os.path.isabs(os.path.expanduser(path)):
            geometry["path"] = os.path.abspath(os.path.join(directory, path))
    return data


def read_case_dict(source: str | Path) -> dict[str, Any]:
    """Read a case file, or a built-in case by name, into a plain dict (not yet validated).
    The relative paths of particle files are made relative to the case file's directory."""
    path = Path(source)
    if not path.suffix and str(source) in BUILTIN_CASES:
        path = builtin_case_path(str(source))
    elif not path.exists():
        if path.suffix:
            raise CaseError(f"case file {str(source)!r} does not exist")
        raise CaseError(f"case {str(source)!r} is neither a file nor a built-in case; "
                        f"built-in cases: {', '.join(BUILTIN_CASES)}")
    try:
        with open(path, "rb") as fh:
            return resolve_paths(tomllib.load(fh), path.absolute().parent)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise CaseError(f"{path}: not valid UTF-8: {exc}") from None
    except OSError as exc:
        raise CaseError(f"case file {str(path)!r} cannot be read: {exc.strerror or exc}"
                        ) from None


def parse_override(text: str) -> tuple[list[str], Any]:
    """``'a.b.0.c=value'`` -> (['a', 'b', '0', 'c'], value); the value is read as TOML
    (numbers, booleans, strings in quotes, arrays) and otherwise kept as a bare string."""
    if "=" not in text:
        raise CaseError(f"--set {text!r}: expected KEY=VALUE, e.g. viscosity.alpha1=0.3")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise CaseError(f"--set {text!r}: the key must be a dotted path such as time.end")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def apply_overrides(data: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Apply ``--set`` overrides to a case dict (a copy is returned)."""
    data = copy.deepcopy(data)
    for text in overrides:
        path, value = parse_override(text)
        node: Any = data
        for depth, part in enumerate(path[:-1]):
            where = ".".join(path[: depth + 1])
            if isinstance(node, list):
                if not part.isdecimal() or int(part) >= len(node):
                    raise CaseError(f"--set {text}: {where} is not an index of a list of "
                                    f"{len(node)}")
                node = node[int(part)]
            elif isinstance(node, dict):
                node = node.setdefault(part, {})
            else:
                raise CaseError(f"--set {text}: {where} is not a table")
        last = path[-1]
        if isinstance(node, list):
            if not last.isdecimal() or int(last) >= len(node):
                raise CaseError(f"--set {text}: index {last} is out of range")
            node[int(last)] = value
        elif isinstance(node, dict):
            node[last] = value
        else:
            raise CaseError(f"--set {text}: {'.'.join(path[:-1])} is not a table")
    return data


_TYPE_TAGS = {"constrained-float", "constrained-int", "float", "int", "str", "bool", "list",
              "dict", "nullable"}


def _is_type_tag(part: object) -> bool:
    """Pydantic's names of union members in an error location (not field names)."""
    return isinstance(part, str) and (part in _TYPE_TAGS
                                      or re.match(r"^[a-z-]+\[", part) is not None)


def _location(loc: tuple[Any, ...]) -> str:
    """The dotted field path of an error location, without pydantic's names of union members
    (``constrained-float``, ...) and of the geometry's type (``bodies.0.geometry.disk.radius``
    is ``bodies.0.geometry.radius``)."""
    parts = [p for k, p in enumerate(loc) if not _is_type_tag(p)
             and not (k > 0 and loc[k - 1] == "geometry" and p in GEOMETRY_TYPES)]
    return ".".join(str(p) for p in parts)


def _format_error(exc: ValidationError) -> str:
    errors = exc.errors()
    err = errors[0]
    loc = _location(err["loc"])
    msg = err["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    value = err.get("input")
    if err["type"] == "geometry_type" and isinstance(value, dict):
        loc, value = f"{loc}.type", value.get("type")
    more = f" (and {len(errors) - 1} more errors)" if len(errors) > 1 else ""
    if err["type"] == "extra_forbidden":
        return f"{loc}: unknown key{more}"
    if err["type"] == "missing":
        return f"{loc}: required field is missing{more}"
    if loc and not isinstance(value, dict):
        return f"{loc} = {value!r}: {msg}{more}"
    return f"{loc + ': ' if loc else ''}{msg}{more}"


def validate_case(data: dict[str, Any]) -> Case:
    """Validate a case dict; raise :class:`CaseError` with a one-line message."""
    try:
        return Case.model_validate(data)
    except ValidationError as exc:
        raise CaseError(_format_error(exc)) from None


def check_particle_files(case: Case) -> None:
    """Read every particle file of the case's ``type = "file"`` geometries; raise
    :class:`CaseError` naming the field for a file that is missing or malformed."""
    from .geometry import read_particle_file

    for k, body in enumerate(case.bodies):
        if isinstance(body.geometry, ParticleFile):
            read_particle_file(body.geometry.path, case.dimension,
                               where=f"bodies.{k}.geometry.path")


def load_case(source: str | Path, overrides: list[str] | None = None) -> Case:
    """Load and validate a case file or built-in case, with optional ``--set`` overrides, and
    check the particle files it reads."""
    case = validate_case(apply_overrides(read_case_dict(source), overrides or []))
    check_particle_files(case)
    return case
