"""Particle geometry: the particles of a body, from lattices filling simple shapes or from a
file.

Every geometry gives :class:`Particles`: positions, a volume per particle (per unit
cross-section in 1D, per unit depth in 2D) and the spacing the smoothing length is scaled from.
:func:`body_particles` picks the function of a case's ``[bodies.geometry]`` table by its
``type``; :func:`read_particle_file` reads and checks a particle file.
"""

from __future__ import annotations

import csv
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import CaseError

AXES = "xyz"


@dataclass
class Particles:
    """The particles of one body."""

    position: np.ndarray  #: (n, dim), m
    volume: np.ndarray  #: (n,), m^dim: the mass is ``density * volume``
    spacing: float  #: m: the smoothing length is ``h_over_dx * spacing``
    #: (n, dim) m/s, a particle file's velocity columns (added to the body's velocity)
    velocity: np.ndarray | None = None
    #: (n,) K, a particle file's initial temperatures
    temperature: np.ndarray | None = None
    #: (n, 3, 3) Pa, a particle file's initial Cauchy stress (tension positive)
    stress: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.position.shape[0]


def block_lattice(origin: list[float], size: list[float], spacing: list[float]) -> np.ndarray:
    """Particles at the cell centres of a regular lattice filling the box
    ``[origin, origin + size]``: ``round(size / spacing)`` particles per axis (``spacing``
    per axis).  Returns positions of shape ``(n, dim)``, x fastest."""
    origin = np.asarray(origin, dtype=np.float64)
    spacing = np.broadcast_to(np.asarray(spacing, dtype=np.float64), origin.shape)
    counts = np.maximum(1, np.rint(np.asarray(size) / spacing).astype(int))
    axes = [origin[a] + (np.arange(counts[a]) + 0.5) * spacing[a] for a in range(origin.size)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel(order="F") for g in grid], axis=1)


def block_particles(origin: list[float], size: list[float], spacing: list[float]) -> Particles:
    """A block (a line in 1D, a rectangle in 2D, a box in 3D): the lattice of
    :func:`block_lattice`; each particle has the cell's volume, the product of the spacings, and
    the spacing for h is their geometric mean (the spacing itself on a square lattice)."""
    x = block_lattice(origin, size, spacing)
    cell = float(np.prod(spacing))
    return Particles(x, np.full(x.shape[0], cell), cell ** (1.0 / len(origin)))


def _disk_offsets(radius: float, spacing: float, inner: float = 0.0) -> np.ndarray:
    """Offsets (n, 2) from a disk's centre of the cell centres ``((i + 1/2) dx, (j + 1/2) dx)``
    of a square lattice, with a cell corner at the centre, that lie within ``radius`` (closed)
    and, for an annulus, at least ``inner`` from the centre; x fastest."""
    half = int(math.ceil(radius / spacing))
    k = np.arange(-half, half) + 0.5  # in units of dx, symmetric about 0
    a, b = np.meshgrid(k, k, indexing="ij")
    a, b = a.ravel(order="F"), b.ravel(order="F")
    r2 = a * a + b * b
    keep = r2 <= (radius / spacing) ** 2
    if inner > 0.0:
        keep &= r2 >= (inner / spacing) ** 2
    return np.stack([a[keep], b[keep]], axis=1) * spacing


def disk_particles(centre: list[float], radius: float, spacing: float) -> Particles:
    """A disk (2D): the cell centres of a square lattice of spacing ``dx`` with a cell corner at
    ``centre`` (particles at ``centre + ((i + 1/2) dx, (j + 1/2) dx)``, none at the centre
    itself) whose distance from the centre is at most ``radius``.  Each particle has the volume
    ``dx^2`` (per unit depth), so the total is ``pi r^2`` up to the lattice's staircase error,
    which falls as ``dx / r`` (under 1 % for ``r >= 10 dx``)."""
    x = np.asarray(centre, dtype=np.float64) + _disk_offsets(radius, spacing)
    return Particles(x, np.full(x.shape[0], spacing**2), float(spacing))


def ring_particles(centre: list[float], inner_radius: float, outer_radius: float,
                   spacing: float) -> Particles:
    """An annulus (2D): the lattice of :func:`disk_particles` kept where the distance from
    ``centre`` is between ``inner_radius`` and ``outer_radius`` (both closed).  Each particle
    has the volume ``dx^2`` (per unit depth); the total is ``pi (r_o^2 - r_i^2)`` up to the
    lattice's staircase error at both circles."""
    x = np.asarray(centre, dtype=np.float64) + _disk_offsets(outer_radius, spacing,
                                                             inner_radius)
    return Particles(x, np.full(x.shape[0], spacing**2), float(spacing))


def sphere_particles(centre: list[float], radius: float, spacing: float) -> Particles:
    """A ball (3D): the cell centres of a cubic lattice of spacing ``dx`` with a cell corner at
    ``centre`` whose distance from it is at most ``radius``; each of volume ``dx^3``, so the
    total is ``4/3 pi r^3`` up to the lattice's staircase error."""
    half = int(math.ceil(radius / spacing))
    k = np.arange(-half, half) + 0.5
    a, b, c = np.meshgrid(k, k, k, indexing="ij")
    offsets = np.stack([a.ravel(order="F"), b.ravel(order="F"), c.ravel(order="F")], axis=1)
    keep = np.einsum("ia,ia->i", offsets, offsets) <= (radius / spacing) ** 2
    x = np.asarray(centre, dtype=np.float64) + offsets[keep] * spacing
    return Particles(x, np.full(x.shape[0], spacing**3), float(spacing))


def fibonacci_sphere(n: int, turn: float = 0.0) -> np.ndarray:
    """``n`` points spread evenly over the unit sphere (n, 3): the Fibonacci spiral, each point
    at an equal share of the area (``z = 1 - (2i + 1) / n``) and the golden angle from the
    last, the whole turned by ``turn`` (rad) about z."""
    i = np.arange(n)
    z = 1.0 - (2.0 * i + 1.0) / n
    rho = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = i * math.pi * (3.0 - math.sqrt(5.0)) + turn
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def sphere_shell_particles(centre: list[float], radius: float, spacing: float) -> Particles:
    """A ball (3D) of ``K = round(radius / spacing)`` concentric shells of thickness ``dr =
    radius / K``: shell ``k`` (0 to K - 1) at ``(k + 1/2) dr`` from the centre holds ``round(V_k
    / dr^3)`` points (at least one) of a Fibonacci spiral (:func:`fibonacci_sphere`, each
    shell turned by the golden angle from the last), which share its volume ``V_k = 4/3 pi
    ((k + 1)^3 - k^3) dr^3``.  The volumes add up to ``4/3 pi r^3`` exactly; the outermost
    particles lie half a spacing inside the surface, on a round one (the lattice's sphere has
    flat facets at its poles: docs/stabilisation.md, "Contact between total-Lagrangian
    bodies")."""
    shells = max(1, round(radius / spacing))
    dr = radius / shells
    points, volumes = [], []
    for k in range(shells):
        shell_volume = 4.0 / 3.0 * math.pi * ((k + 1) ** 3 - k**3) * dr**3
        count = max(1, round(shell_volume / dr**3))
        turn = k * math.pi * (3.0 - math.sqrt(5.0))
        points.append(fibonacci_sphere(count, turn) * (k + 0.5) * dr)
        volumes.append(np.full(count, shell_volume / count))
    x = np.asarray(centre, dtype=np.float64) + np.concatenate(points)
    return Particles(x, np.concatenate(volumes), float(dr))


def cylinder_particles(centre: list[float], radius: float, length: float, axis: str,
                       spacing: float, arrangement: str = "lattice") -> Particles:
    """A circular cylinder (3D) along ``axis`` (``"x"``, ``"y"`` or ``"z"``) from the base
    centred at ``centre`` in the positive direction.  ``arrangement``:

    - ``"lattice"``: ``round(length / spacing)`` layers (at least 1) at ``(k + 1/2) dx`` from
      the base, each the lattice of :func:`disk_particles` across the axis (the other two axes
      in the order x, y, z).  Each particle has the volume ``dx^3``; the total is ``pi r^2 L``
      up to the disk's lattice error and the rounding of ``L`` to whole layers.
    - ``"rings"``: ``round(length / spacing)`` layers of thickness ``dz = L / layers``, each of
      ``K = round(radius / spacing)`` concentric rings (:func:`ring_offsets`); the volumes add
      up to ``pi r^2 L`` exactly, the outermost particles lie half a ring's width inside a
      round surface, and no line of particles runs across the section (the lattice's rows,
      columns and diagonals are the directions along which a flattening foot streams out:
      docs/validation.md, "Taylor bar in 3D").  ``Particles.spacing`` is the geometric mean
      ``(dr^2 dz)^(1/3)``.
    """
    along = AXES.index(axis)
    across = [a for a in range(3) if a != along]
    layers = whole_count(length, spacing)
    if arrangement == "rings":
        disk, areas, dr = ring_offsets(radius, spacing)
        dz = length / layers
        volume = np.tile(areas * dz, layers)
        mean_spacing = float((dr * dr * dz) ** (1.0 / 3.0))
    elif arrangement == "lattice":
        disk = _disk_offsets(radius, spacing)
        dz = spacing
        volume = np.full(layers * disk.shape[0], spacing**3)
        mean_spacing = float(spacing)
    else:
        raise ValueError(f"arrangement = {arrangement!r}: allowed 'lattice' or 'rings'")
    x = np.empty((layers * disk.shape[0], 3))
    x[:, across] = np.tile(disk, (layers, 1))
    x[:, along] = np.repeat((np.arange(layers) + 0.5) * dz, disk.shape[0])
    x += np.asarray(centre, dtype=np.float64)
    return Particles(x, volume, mean_spacing)


def whole_count(extent: float, spacing: float) -> int:
    """How many layers (or rings) of about ``spacing`` fill ``extent``: ``round(extent /
    spacing)``, at least 1 (a cylinder's layers; its rings with ``arrangement = "rings"``,
    whose width and thickness are then ``extent / whole_count``)."""
    return max(1, round(extent / spacing))


def ring_offsets(radius: float, spacing: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A disk of ``K = max(1, round(radius / spacing))`` concentric rings of width ``dr =
    radius / K``: ring ``k`` (0 to K - 1) at ``(k + 1/2) dr`` from the centre holds ``n_k = 4
    max(1, round(2 pi (k + 1/2) / 4))`` points at the angles ``(j + 1/2) 2 pi / n_k``, which
    share its area ``pi ((k + 1)^2 - k^2) dr^2``.  A multiple of 4 with the half-step offset
    makes each ring mirror-symmetric about both axes with no point on either, so a quarter
    (x > 0, y > 0) with two symmetry planes is the whole disk (:func:`quarter_cylinder_case`).
    Returns the offsets (n, 2), the areas (n,) and ``dr``."""
    rings = whole_count(radius, spacing)
    dr = radius / rings
    offsets, areas = [], []
    for k in range(rings):
        count = 4 * max(1, round(2.0 * math.pi * (k + 0.5) / 4.0))
        angle = (np.arange(count) + 0.5) * (2.0 * math.pi / count)
        r = (k + 0.5) * dr
        offsets.append(np.stack([r * np.cos(angle), r * np.sin(angle)], axis=1))
        areas.append(np.full(count, math.pi * (2 * k + 1) * dr * dr / count))
    return np.concatenate(offsets), np.concatenate(areas), float(dr)


def quarter_planes() -> list[dict[str, Any]]:
    """The two symmetry planes through the z axis that make a quarter model of x > 0, y > 0
    (new tables each call: a case may change them)."""
    return [{"type": "symmetry", "point": [0.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]},
            {"type": "symmetry", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0]}]


def quarter_file_geometry(particles: Particles, path: Path) -> dict[str, Any]:
    """The particles with x > 0, y > 0 written to ``path`` (``.npz``), as the geometry table
    of a file body (the quarter of a body symmetric about the z axis)."""
    x = particles.position
    keep = (x[:, 0] > 0) & (x[:, 1] > 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, position=x[keep], volume=particles.volume[keep])
    return {"type": "file", "path": str(path.resolve()), "spacing": particles.spacing}


def quarter_cylinder_case(case: dict[str, Any], folder: Path) -> dict[str, Any]:
    """A case dict whose first body is a cylinder along z with its axis at x = y = 0 (the
    Taylor bar in 3D), cut to its quarter x > 0, y > 0: the quarter's particles written to
    ``folder`` (:func:`quarter_file_geometry`) and the two symmetry planes through the axis
    (:func:`quarter_planes`) added to the boundaries.  Four times cheaper; it equals the whole
    cylinder to round-off (tests/test_symmetry.py).  ``case`` is changed in place and
    returned."""
    g = case["bodies"][0]["geometry"]
    if (g.get("type") != "cylinder" or g.get("axis") != "z"
            or any(abs(float(c)) > 0.0 for c in g["centre"][:2])):
        raise CaseError("bodies.0.geometry: the quarter needs a cylinder along z with its "
                        f"axis at x = y = 0, not {g!r}")
    particles = cylinder_particles(g["centre"], g["radius"], g["length"], g["axis"],
                                   g["spacing"], g.get("arrangement", "lattice"))
    case["bodies"][0]["geometry"] = quarter_file_geometry(
        particles, folder / f"{case['name']}-{g['spacing']:.4e}-{g.get('arrangement', 'lattice')}"
                            "-quarter.npz")
    case["boundaries"] = [*case.get("boundaries", []), *quarter_planes()]
    return case


def file_particles(path: str | Path, dim: int, spacing: float,
                   where: str = "geometry.path") -> Particles:
    """Particles read from a CSV or NPZ file (see :func:`read_particle_file`); a particle
    without a volume in the file has the volume ``spacing^dim``; h is scaled from
    ``spacing``."""
    x, volume, extra = _read_particle_file(path, dim, where)
    if volume is None:
        volume = np.full(x.shape[0], float(spacing) ** dim)
    return Particles(x, volume, float(spacing), extra.get("velocity"), extra.get("temperature"),
                     extra.get("stress"))


def body_particles(geometry: Any, dim: int, where: str = "geometry") -> Particles:
    """The particles of a validated ``[bodies.geometry]`` table (a
    :class:`~impactsph.config.Block`, ``Disk``, ``Ring``, ``Cylinder``, ``Sphere`` or
    ``ParticleFile``); ``where`` names it in error messages."""
    kind = geometry.type
    if kind == "block":
        return block_particles(geometry.origin, geometry.size, geometry.spacings())
    if kind == "disk":
        return disk_particles(geometry.centre, geometry.radius, geometry.spacing)
    if kind == "ring":
        return ring_particles(geometry.centre, geometry.inner_radius, geometry.outer_radius,
                              geometry.spacing)
    if kind == "sphere":
        if geometry.arrangement == "shells":
            return sphere_shell_particles(geometry.centre, geometry.radius, geometry.spacing)
        return sphere_particles(geometry.centre, geometry.radius, geometry.spacing)
    if kind == "cylinder":
        return cylinder_particles(geometry.centre, geometry.radius, geometry.length,
                                  geometry.axis, geometry.spacing, geometry.arrangement)
    if kind == "file":
        return file_particles(geometry.path, dim, geometry.spacing, where=f"{where}.path")
    raise ValueError(f"unknown geometry type {kind!r}")


def inside(x: np.ndarray, origin: list[float], size: list[float]) -> np.ndarray:
    """Mask of the points inside the closed box ``[origin, origin + size]``."""
    lo = np.asarray(origin, dtype=np.float64)
    hi = lo + np.asarray(size, dtype=np.float64)
    return np.all((x >= lo) & (x <= hi), axis=1)


# -- particle files ---------------------------------------------------------------------------


def read_particle_file(path: str | Path, dim: int, where: str = "geometry.path"
                       ) -> tuple[np.ndarray, np.ndarray | None]:
    """Read particles from ``path``: positions ``(n, dim)`` and volumes ``(n,)`` (None when the
    file gives none).

    - ``.csv``: a header naming the columns, ``x`` (``x, y`` in 2D, ``x, y, z`` in 3D) and
      optionally ``volume``, the velocity ``vx`` (``vx, vy``, ``vx, vy, vz``: all or none),
      ``temperature`` and the initial Cauchy stress (Pa, tension positive; in 2D
      ``sigma_xx, sigma_yy, sigma_zz, sigma_xy``, in 3D those and ``sigma_xz, sigma_yz``:
      all or none), in any order, then one particle per line; blank lines and lines starting
      with ``#`` are skipped.
    - ``.npz``: the arrays ``position`` of shape ``(n, dim)`` (``(n,)`` in 1D too) and
      optionally ``volume`` and ``temperature`` of shape ``(n,)``, ``velocity`` of shape
      ``(n, dim)`` and ``stress`` of shape ``(n, 3, 3)`` (symmetric; in 2D without ``xz`` and
      ``yz`` components).

    Every coordinate, velocity, temperature and stress must be finite, every volume and
    temperature > 0, and the file must hold at least one particle; 1D files carry no
    stress.  Raises
    :class:`~impactsph.errors.CaseError`, one line starting with ``where = 'PATH': ``, for a
    file that is missing, unreadable or malformed.  The velocity and temperature:
    :func:`file_particles`."""
    x, volume, _ = _read_particle_file(path, dim, where)
    return x, volume


def _read_particle_file(path: str | Path, dim: int, where: str
                        ) -> tuple[np.ndarray, np.ndarray | None, dict[str, np.ndarray]]:
    path = Path(path)

    def fail(msg: str) -> CaseError:
        return CaseError(f"{where} = {str(path)!r}: {msg}")

    if not path.exists():
        raise fail("file does not exist")
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".npz"):
        raise fail("a particle file must be .csv or .npz")
    try:
        if suffix == ".csv":
            x, volume, extra = _read_csv(path, dim, fail)
        else:
            x, volume, extra = _read_npz(path, dim, fail)
    except CaseError:
        raise
    except UnicodeDecodeError as exc:
        raise fail(f"not valid UTF-8: {exc}") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise fail(f"cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    if x.shape[0] == 0:
        raise fail("holds no particle")
    bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
    if bad.size:
        raise fail(f"particle {int(bad[0])} has a non-finite position {x[bad[0]].tolist()}")
    if volume is not None:
        bad = np.flatnonzero(~(np.isfinite(volume) & (volume > 0)))
        if bad.size:
            raise fail(f"particle {int(bad[0])} has the volume {float(volume[bad[0]])!r}; "
                       f"volumes must be finite and > 0")
    if "velocity" in extra:
        v = extra["velocity"]
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if bad.size:
            raise fail(f"particle {int(bad[0])} has a non-finite velocity {v[bad[0]].tolist()}")
    if "temperature" in extra:
        T = extra["temperature"]
        bad = np.flatnonzero(~(np.isfinite(T) & (T > 0)))
        if bad.size:
            raise fail(f"particle {int(bad[0])} has the temperature {float(T[bad[0]])!r}; "
                       f"temperatures (K) must be finite and > 0")
    if "stress" in extra:
        _check_stress(extra["stress"], dim, fail)
    return np.ascontiguousarray(x, dtype=np.float64), volume, extra


def _check_stress(stress: np.ndarray, dim: int, fail) -> None:
    """A file's initial stresses: finite, symmetric, in 2D without out-of-plane shear."""
    bad = np.flatnonzero(~np.isfinite(stress).all(axis=(1, 2)))
    if bad.size:
        raise fail(f"particle {int(bad[0])} has a non-finite stress")
    asym = np.abs(stress - stress.transpose(0, 2, 1)).max(axis=(1, 2))
    bad = np.flatnonzero(asym > 1e-12 * np.abs(stress).max(axis=(1, 2)))
    if bad.size:
        raise fail(f"particle {int(bad[0])}'s stress is not symmetric; a Cauchy stress is")
    if dim == 2:
        bad = np.flatnonzero(np.abs(stress[:, 2, :2]).max(axis=1) > 0.0)
        if bad.size:
            raise fail(f"particle {int(bad[0])} has out-of-plane shear stress (xz or yz); a 2D "
                       f"body has none")


VELOCITY_COLUMNS = ("vx", "vy", "vz")
#: a particle file's stress columns by dimension (row, column of the 3x3 Cauchy stress)
STRESS_COLUMNS = {
    1: {},
    2: {"sigma_xx": (0, 0), "sigma_yy": (1, 1), "sigma_zz": (2, 2), "sigma_xy": (0, 1)},
    3: {"sigma_xx": (0, 0), "sigma_yy": (1, 1), "sigma_zz": (2, 2), "sigma_xy": (0, 1),
        "sigma_xz": (0, 2), "sigma_yz": (1, 2)},
}


def _read_csv(path: Path, dim: int, fail):
    expected = list(AXES[:dim])
    speeds = list(VELOCITY_COLUMNS[:dim])
    stresses = list(STRESS_COLUMNS[dim])
    allowed = (f"{', '.join(expected)} and optionally volume, {', '.join(speeds)}"
               + (f", temperature and {', '.join(stresses)}" if stresses else
                  " and temperature"))
    with open(path, newline="", encoding="utf-8-sig") as fh:  # a BOM (spreadsheets) is skipped
        lines = [(k + 1, row) for k, row in enumerate(csv.reader(fh))
                 if row and any(f.strip() for f in row) and not row[0].lstrip().startswith("#")]
    if not lines:
        raise fail(f"is empty; expected a header naming the columns {allowed}")
    line_no, header = lines[0]
    names = [name.strip().lower() for name in header]
    if any(_is_number(name) for name in names):
        raise fail(f"line {line_no}: expected a header naming the columns {allowed}, found "
                   f"{header!r}")
    unknown = [n for n in names
               if n not in (*expected, "volume", *speeds, "temperature", *stresses)]
    some_speeds = set(speeds) & set(names)
    some_stresses = set(stresses) & set(names)
    if (unknown or len(set(names)) != len(names) or not set(expected) <= set(names)
            or (some_speeds and some_speeds != set(speeds))
            or (some_stresses and some_stresses != set(stresses))):
        raise fail(f"has the columns {names!r}; dimension = {dim} needs {allowed}")
    values = np.empty((len(lines) - 1, len(names)))
    for row_index, (line_no, row) in enumerate(lines[1:]):
        if len(row) != len(names):
            raise fail(f"line {line_no} has {len(row)} fields; the header names {len(names)}")
        for col, field in enumerate(row):
            try:
                values[row_index, col] = float(field)
            except ValueError:
                raise fail(f"line {line_no}: {names[col]} = {field.strip()!r} is not a "
                           f"number") from None
    x = values[:, [names.index(a) for a in expected]]
    volume = values[:, names.index("volume")].copy() if "volume" in names else None
    extra = {}
    if some_speeds:
        extra["velocity"] = np.ascontiguousarray(values[:, [names.index(a) for a in speeds]])
    if "temperature" in names:
        extra["temperature"] = values[:, names.index("temperature")].copy()
    if some_stresses:
        stress = np.zeros((values.shape[0], 3, 3))
        for name, (a, b) in STRESS_COLUMNS[dim].items():
            stress[:, a, b] = stress[:, b, a] = values[:, names.index(name)]
        extra["stress"] = stress
    return x, volume, extra


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_npz(path: Path, dim: int, fail):
    data = np.load(path, allow_pickle=False)
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise fail("is not an NPZ archive (a .npy array?)")
    with data:
        known = ("position", "volume", "velocity", "temperature") + (("stress",) if dim > 1
                                                                      else ())
        unknown = [k for k in data.files if k not in known]
        if unknown:
            raise fail(f"holds the unknown array {unknown[0]!r}; expected position and "
                       f"optionally {', '.join(known[1:-1])} and {known[-1]}")
        if "position" not in data.files:
            raise fail("holds no array 'position'")
        x = np.asarray(data["position"])
        volume = np.asarray(data["volume"]) if "volume" in data.files else None
        extra = {k: np.asarray(data[k], dtype=np.float64)
                 for k in ("velocity", "temperature", "stress") if k in data.files}
    if dim == 1 and x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[1] != dim:
        raise fail(f"position has the shape {x.shape}; dimension = {dim} needs (n, {dim})")
    if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
        raise fail(f"position has the type {x.dtype}; expected numbers")
    x = x.astype(np.float64)
    if volume is not None:
        if volume.shape != (x.shape[0],):
            raise fail(f"volume has the shape {volume.shape}; position needs ({x.shape[0]},)")
        if not (np.issubdtype(volume.dtype, np.floating)
                or np.issubdtype(volume.dtype, np.integer)):
            raise fail(f"volume has the type {volume.dtype}; expected numbers")
        volume = volume.astype(np.float64)
    if "velocity" in extra:
        if dim == 1 and extra["velocity"].ndim == 1:
            extra["velocity"] = extra["velocity"][:, None]
        if extra["velocity"].shape != x.shape:
            raise fail(f"velocity has the shape {extra['velocity'].shape}; position needs "
                       f"{x.shape}")
    if "temperature" in extra and extra["temperature"].shape != (x.shape[0],):
        raise fail(f"temperature has the shape {extra['temperature'].shape}; position needs "
                   f"({x.shape[0]},)")
    if "stress" in extra and extra["stress"].shape != (x.shape[0], 3, 3):
        raise fail(f"stress has the shape {extra['stress'].shape}; position needs "
                   f"({x.shape[0]}, 3, 3)")
    return x, volume, extra
