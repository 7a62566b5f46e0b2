"""Checks before a run, and one after it: set-ups that are refused or warned about before any
computation (docs/case-files.md, "Preflight checks").

:func:`preflight` runs on a validated case (``impactsph check``, and ``impactsph run`` before
it starts) and returns a :class:`Report`:

- the **particle count** of each body, counted without placing the particles (so that a case
  of 4e8 particles is refused in a millisecond);
- an **estimate of the memory** a run needs (:func:`memory_estimate`: the arrays the solver
  allocates per particle and per neighbour pair, the snapshots, the history rows, and the
  process's own base, calibrated against the measured peak of real runs) and of its **run
  time** (the steps from the CFL condition, eq 26, times the pair evaluations per step, over a
  pair rate measured on this machine by earlier runs, or :data:`DEFAULT_PAIR_RATE`);
- **errors** (the case is refused, exit code 2): a memory estimate above the memory this
  machine has available, and for a run on a GPU a GPU memory estimate (:func:`device_memory`,
  :mod:`impactsph.gpu_memory`) above the GPU's free memory;
  particles behind a wall at t = 0 (the run would stop at its first step with "particle
  crossed a wall");
- **warnings** (the run goes on): bodies that overlap, duplicate particle positions, too few
  neighbours for the kernel, isolated particles, a body of one particle, and magnitudes that
  are implausible in SI units (a likely unit slip, with the value it probably meant).

Every check is vectorised: the particle checks use the cell-linked neighbour list of
:mod:`impactsph.neighbours` and numpy over the pairs, in chunks, with no loop over particles.

:func:`after_run` is called at the end of ``impactsph run``: it warns when a large share of the
initial kinetic energy remains in a problem that is expected to dissipate it, and keeps the
pair rate the run measured for later estimates.  :func:`compile_notice` says when the SPH
kernels are about to be compiled for the first time.
"""

from __future__ import annotations

import datetime
import json
import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .config import Block, Case, Cylinder, Disk, ParticleFile, Ring, Sphere
from .errors import CaseError
from .initial import max_speed
from .integrate import INTEGRATORS
from .kernels import SUPPORT_RADIUS
from .models.columns import CARRIED, PASS_CARRIED
from .physics.records import record_columns

# -- thresholds (documented in docs/case-files.md, "Preflight checks") ----------------------

#: Neighbours within the kernel support 2h of the best-surrounded particle of a full lattice
#: at h = dx, by dimension: fewer than this and the cubic spline has too few particles to
#: interpolate (h_over_dx below about 1).
MIN_NEIGHBOURS = {1: 2, 2: 8, 3: 26}
#: Particles of two bodies closer than this many spacings overlap.
OVERLAP_SPACINGS = 0.5
#: Particles closer than this many spacings are duplicates (the pair loop skips r = 0).
DUPLICATE_SPACINGS = 1e-6
#: Plausible SI ranges: (low, high) for each kind of quantity.
LENGTH_RANGE = (1e-5, 1.0)  # m: a geometry dimension of an impact specimen
DENSITY_RANGE = (30.0, 3e4)  # kg/m^3: below, the value reads as g/cm^3 (foams aside)
MODULUS_RANGE = (1e5, 2e12)  # Pa: Young's and shear moduli
YIELD_STRESS_MIN = 1e5  # Pa
SPEED_MAX = 2e4  # m/s
END_TIME_MAX = 1.0  # s of simulated time
STEPS_MAX = 1e7
#: Share of the initial kinetic energy that may remain at the end of a dissipative impact.
KINETIC_ENERGY_REMAINING = 0.02

# -- calibration (benchmarks/calibrate_preflight.py; docs/case-files.md) --------------------

#: Resident memory of an ``impactsph run`` process before its particles: Python, numpy,
#: numba and the loaded kernels, matplotlib (bytes): measured 208-213 MB with the kernels
#: cached, 364 MB at the peak of a first run that compiles them.
BASE_MEMORY = 400e6
#: Factor on the arrays counted by :func:`memory_estimate` to reach the measured peak
#: (allocator slack, temporaries of the neighbour build and of the outputs).
MEMORY_SAFETY = 1.25
#: Factor on the GPU arrays of a run on a GPU (:class:`impactsph.gpu_memory.DeviceLayout`,
#: which counts them to within 1% of what the device runs of ``tests/test_gpu_step.py`` hold
#: in numba's CUDA simulator, its state there or its rates alone) for what they
#: may grow to during the run: the neighbour list as the bodies are compressed, the walls'
#: ghosts as more particles come near them.  (The list's radius already takes the stretch's
#: largest h, and the list's indices are counted twice: :func:`device_memory`.)
GPU_MEMORY_SAFETY = 1.1
#: Device memory of a run's GPU kernels and of what numba-cuda keeps beside its arrays
#: (bytes): the whole step's kernels took no measurable share of the 1,080 B a particle
#: measured at 1M and at 1e7 particles in 3D on an H200 (benchmarks/README.md).
GPU_BASE_MEMORY = 100e6
#: Bytes per value of a history row: held in memory (a dict of floats), written as CSV at the
#: end and read back for the figures.
HISTORY_VALUE_BYTES = 180
#: Pair evaluations per second assumed where no run on this machine has measured one: about
#: the slowest rate measured on this project's machine for 2D and 3D runs of 1e4 to 4e5
#: particles, on one numba thread with other jobs running (1.15e7 to 1.3e7 with AC and a
#: wall; benchmarks/calibrate_preflight.py; docs/case-files.md).
DEFAULT_PAIR_RATE = 1e7
#: The same for a run on a GPU: a conservative figure (the whole step on an H200 reached
#: 7.4e9 pair evaluations a second with 1e5 particles in 3D and 1.4e10-1.6e10 with 1e6-1e7,
#: benchmarks/README.md; a smaller GPU, or the rates alone on the GPU, less).
DEFAULT_GPU_PAIR_RATE = 1e9
#: Fixed cost of a step (s): the Python of the step loop, the survey, the history row;
#: measured 100-150 us a step for 50-200 particles in 1D (the bars, calibrate_preflight.py).
STEP_SECONDS = 1e-4
#: Runs with fewer pair evaluations than this do not update the stored pair rate (their
#: time is mostly fixed costs).
MIN_PAIRS_TO_RECORD = 1e6
PAIR_RATE_FILE = "pair_rates.json"
#: A run whose kernel follows the stretch (``kernel.max_stretch`` > 1, the default for a
#: plastic case) against the same run with a fixed kernel: its wall time per pair evaluation
#: (the stretch's estimate at each list build, the larger rows of the stretched particles;
#: 1.11-1.15 on the x2 plane-strain Taylor bar, benchmarks/README.md).  Applied to a rate
#: that a run of the other kind measured, where none of the case's kind has.
STRETCH_COST = 1.13


@dataclass(frozen=True)
class Finding:
    """One warning or error: ``field`` is the dotted path of the case field it is about,
    ``message`` the one line printed (it starts with the field)."""

    level: str  #: "warning" or "error"
    field: str
    message: str

    def line(self) -> str:
        """The line printed for it."""
        return f"{self.level}: {self.message}"


@dataclass
class Estimate:
    """What a run of the case will take (all estimates)."""

    particles: dict[str, int]  #: per body name
    neighbours: float  #: stored neighbour-list entries per particle (support + skin)
    pairs_per_particle: float  #: pair evaluations per particle per rate evaluation
    ghosts: int  #: wall ghosts at t = 0 (0 before the particles are placed)
    memory: float  #: bytes, peak of the process
    available: int | None  #: bytes this machine has available, None if unknown
    dt: float  #: s, the initial step of eq 26
    steps: int
    pair_rate: float  #: pair evaluations per second assumed
    pair_rate_source: str
    seconds: float  #: wall time of the steps (compilation excluded)
    runs: int = 1  #: 2 with a reference run (output.reference_viscosity)
    dt_source: str = "eq 26"  #: what set ``dt``
    #: bytes of GPU memory, peak, of a run on a GPU (its state there, or its rates alone);
    #: None for a run on the CPU
    device_memory: float | None = None
    #: free bytes of the GPU the run will use, None where unknown (numba's CUDA simulator)
    device_available: int | None = None
    device_name: str = ""  #: the GPU's name
    device_line: str = ""  #: what the run will do on a GPU it asked for (:func:`device_plan`)
    state_on_gpu: bool = False  #: whether the run's state stays on the GPU
    #: the particles' numbering where it matters (:func:`order_line`), else empty
    order_line: str = ""
    #: s, where the steps start: a restart's checkpoint time (``steps`` and ``seconds`` are
    #: then those left to ``time.end``)
    start: float = 0.0

    @property
    def total(self) -> int:
        """All particles."""
        return sum(self.particles.values())

    def lines(self) -> list[str]:
        """The lines printed for it."""
        parts = ", ".join(f"{name} {n:,}" for name, n in self.particles.items())
        avail = (f" of {_bytes(self.available)} available" if self.available is not None
                 else "")
        return [
            f"particles: {parts}; total {self.total:,}"
            + (f" (+ {self.ghosts:,} wall ghosts)" if self.ghosts else ""),
            *([self.device_line] if self.device_line else []),
            f"estimated memory: {_bytes(self.memory)}{avail}",
            *([f"estimated GPU memory: {_bytes(self.device_memory)}"
               + (f" of {_bytes(self.device_available)} free on the {self.device_name}"
                  if self.device_available is not None else f" ({self.device_name})")]
              if self.device_memory is not None else []),
            f"estimated run time: {_duration(self.seconds)} ("
            + ("two runs, the case's and its reference_viscosity's, each " if self.runs > 1
               else "")
            + f"{self.steps:,} step{'' if self.steps == 1 else 's'} of "
            f"dt = {self.dt:.3g} s by {self.dt_source}"
            + (f" from the checkpoint's t = {self.start:.6g} s" if self.start > 0.0 else "")
            + f", {self.pairs_per_particle:.3g} pairs per "
            f"particle, "
            f"{self.pair_rate:.3g} pairs/s {self.pair_rate_source}; an estimate, compilation "
            f"excluded)",
            *([self.order_line] if self.order_line else []),
        ]


@dataclass
class Report:
    """The estimate and the findings of :func:`preflight`."""

    estimate: Estimate
    findings: list[Finding] = field(default_factory=list)

    @property
    def errors(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "error"]

    @property
    def warnings(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "warning"]

    def lines(self) -> list[str]:
        """Estimate lines, then one line per finding."""
        return [*self.estimate.lines(), *(f.line() for f in self.findings)]


def label_of(case: Any) -> str:
    """Short label of a run's viscosity settings, e.g. ``AV (0.3, 0.3)``, ``AC (shepard)``,
    ``balsara (1, 1)``: another scheme by its name and the coefficients its pair term uses;
    ``, total-Lagrangian`` after it for that formulation."""
    from .models import VISCOSITY

    v = case.viscosity
    if v.scheme == "ac":
        return f"AC ({v.correction})"
    alpha1, alpha2 = VISCOSITY[v.scheme].pair_parameters(v)[:2]
    name = "AV" if v.scheme == "av" else v.scheme
    limiter = getattr(v, "limiter", "van_leer")
    suffix = f", {limiter}" if limiter != "van_leer" else ""
    formulation = (", total-Lagrangian"
                   if getattr(case, "formulation", "") == "total_lagrangian" else "")
    return f"{name} ({alpha1:g}, {alpha2:g}{suffix}){formulation}"


def scheme_line(case: Case) -> str:
    """One line that says which discretisation the case runs, its ``"auto"`` defaults
    resolved (docs/stabilisation.md, "Defaults, and why"): the viscosity, the formulation,
    the kernel, the stabilisation and the walls' contact options."""
    widths = sorted({case.h_over_dx_of(b) for b in range(len(case.bodies))})
    h = " and ".join(f"{_g(w)}" for w in widths)
    stretch = case.kernel.max_stretch
    kernel = (f"h = {h} dx, growing with the stretch to {_g(stretch)} h0 (kernel.max_stretch)"
              if stretch > 1.0 else f"h = {h} dx, fixed")
    parts = [label_of(case)]  # says ", total-Lagrangian" for that formulation
    if case.formulation != "total_lagrangian":
        parts[0] += ", updated-Lagrangian"
    parts.append(kernel)
    if case.formulation != "total_lagrangian":
        stab = case.stabilisation
        parts.append(f"gradient correction {stab.gradient_correction.replace('_', ' ')}, "
                     f"hourglass {_g(stab.hourglass)}")
        if stab.artificial_stress > 0.0:
            parts.append(f"artificial stress {_g(stab.artificial_stress)}")
    if any(b.type == "wall" for b in case.boundaries):
        parts.append(f"walls: {case.contact.traction.replace('_', ' ')} traction, layer "
                     f"{_g(case.contact.wall_layer)}")
    return "scheme: " + "; ".join(parts)


# -- formatting ------------------------------------------------------------------------------

def _bytes(n: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def _duration(s: float) -> str:
    if not math.isfinite(s):
        return "unknown"
    if s < 60:
        return f"{s:.2g} s"
    if s < 3600:
        return f"{s / 60:.2g} min"
    if s < 86400:
        return f"{s / 3600:.2g} h"
    return f"{s / 86400:.3g} days"


def _plural(n: int, noun: str) -> str:
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _g(x: float) -> str:
    return f"{x:.4g}"


# -- particle counts, without placing the particles ----------------------------------------

def _disk_count(radius: float, spacing: float) -> int:
    """Particles of :func:`impactsph.geometry.disk_particles` (the same lattice and test),
    counted in chunks of rows."""
    half = int(math.ceil(radius / spacing))
    k = np.arange(-half, half) + 0.5
    k2 = k * k
    rho2 = (radius / spacing) ** 2
    total = 0
    for start in range(0, k2.size, 1024):
        total += int(np.count_nonzero(k2[start:start + 1024, None] + k2[None, :] <= rho2))
    return total


def body_spacing(geometry: Any) -> float:
    """The spacing dx the smoothing length is scaled from (a block's geometric mean)."""
    if isinstance(geometry, Block):
        return float(np.prod(geometry.spacings())) ** (1.0 / len(geometry.size))
    if isinstance(geometry, Cylinder) and geometry.arrangement == "rings":
        return float(np.prod(geometry.spacings())) ** (1.0 / 3.0)  # (dr^2 dz)^(1/3)
    return float(geometry.spacing)


def count_particles(case: Case) -> list[int]:
    """Particles of each body, as :func:`impactsph.problem.build_problem` places them, counted
    without placing them (a particle file is read)."""
    counts = []
    for body in case.bodies:
        g = body.geometry
        if isinstance(g, Block):
            if g.count is not None:
                n = math.prod(g.count)
            else:
                sizes = np.asarray(g.size, dtype=np.float64)
                spacing = np.broadcast_to(np.asarray(g.spacings(), dtype=np.float64),
                                          sizes.shape)
                n = math.prod(int(c) for c in np.maximum(1, np.rint(sizes / spacing)))
        elif isinstance(g, Cylinder):
            from .geometry import ring_offsets, whole_count

            if g.arrangement == "rings":
                section = ring_offsets(g.radius, g.spacing)[0].shape[0]
            else:
                section = _disk_count(g.radius, g.spacing)
            n = section * whole_count(g.length, g.spacing)
        elif isinstance(g, Disk):
            n = _disk_count(g.radius, g.spacing)
        elif isinstance(g, Ring | Sphere):
            from .geometry import body_particles

            n = body_particles(g, case.dimension).position.shape[0]
        else:
            from .geometry import read_particle_file

            n = read_particle_file(g.path, case.dimension)[0].shape[0]
        counts.append(int(n))
    return counts


def _size_field(case: Case, b: int) -> str:
    """The field that sets the number of particles of body ``b``."""
    g = case.bodies[b].geometry
    if isinstance(g, Block):
        return f"bodies.{b}.geometry.{'count' if g.count is not None else 'spacing'}"
    if isinstance(g, ParticleFile):
        return f"bodies.{b}.geometry.path"
    return f"bodies.{b}.geometry.spacing"


def _field_value(case: Case, path: str) -> Any:
    node: Any = case
    for part in path.split("."):
        node = node[int(part)] if part.isdecimal() else getattr(node, part)
    return node


# -- memory and time -------------------------------------------------------------------------

def lattice_neighbours(radius_over_dx: float, dim: int) -> float:
    """Neighbours (self excluded) within ``radius_over_dx`` spacings of a particle inside a
    lattice: the volume of the ball in cells, less one."""
    r = radius_over_dx
    volume = {1: 2.0 * r, 2: math.pi * r * r, 3: 4.0 / 3.0 * math.pi * r ** 3}[dim]
    return max(0.0, volume - 1.0)


def state_bytes(dim: int, strength_width: int, hourglass: bool = False) -> int:
    """Bytes per particle of :class:`impactsph.state.ParticleState` as a run holds it: its
    positions, velocity, density, energy, deviator, mass, smoothing length, body, material,
    clamp, plastic work, material state and hourglass acceleration; not a viscosity switch's
    factor and memory, nor the added masses (views of one number in a run without a switch
    or without added mass; a snapshot copies them whole: :func:`memory_estimate`)."""
    return (24 * dim + 121 + 8 * strength_width + (8 * dim if hourglass else 0))


def memory_estimate(n: int, dim: int, neighbours: float, *, ghosts: int = 0,
                    corrected: bool = False, walls: bool = False, contact: bool = False,
                    hourglass: bool = False,
                    force_correction: bool = False, strength_width: int = 1,
                    state_kept: int | None = None, snapshots: int = 0, history_values: int = 0,
                    compatible: bool = False, switched: bool = False,
                    inner_list: bool = False, gpu_state: bool = False) -> float:
    """Peak bytes of a run of ``n`` particles (``ghosts`` more in the sums) with ``neighbours``
    stored neighbour-list entries per particle:

    - per particle: the state (:func:`state_bytes`; 16 bytes more with a switch, its factor
      and memory, which are views of one number without one), the integrator's copy of its
      integrated fields (of the material state the first ``state_kept`` columns, those a
      model changes: :func:`state_kept`; None: all ``strength_width``), and ``snapshots`` copies
      of the state (its views copied whole, plus the pressure, the von Mises stress and the
      common material state's columns) kept for ``snapshots.npz``;
    - per particle and ghost: the rate buffers (``RateBuffers``), the packed particle records
      (unpadded: 10 to 22 doubles without the optional columns, the viscous acceleration's
      only with a correction or a switch), the extended arrays of the wall ghosts (with
      ``walls``), the neighbour list's offsets, order and reference positions (and in 2D and
      3D its rows' splits; with ``inner_list``, a scheme whose correction or switch reads the
      list's inner list on the CPU, the rows' inner ends), and the builder's temporaries
      (cell keys, sort order, sorted positions; the cells' counts and the occupied cells'
      Morton codes are a few bytes);
    - per stored neighbour pair: 4 bytes (int32 index);
    - ``history_values`` numbers of the history and the probes (:data:`HISTORY_VALUE_BYTES`
      each, :func:`history_values`);
    - with ``compatible`` (the compatible energy update), per particle and ghost: the work
      velocity's record columns, the work pass's rate buffers, the corrector's pair energy
      rates, the work velocity and its sorted copy;
    - with ``walls`` or ``switched`` (a viscosity scheme with a switch), per particle and
      ghost: the passes' copy of the common material state (``Solver._arrays``);
    - with ``walls``, less per particle the state's fields that are views of the extended
      arrays' rows (``Solver._allocate``): position, velocity, density, energy and
      deviatoric stress, and without a switch the material state (whose width the extended
      carried array then takes);

    times :data:`MEMORY_SAFETY`, plus :data:`BASE_MEMORY` for the process itself.  With
    ``gpu_state`` (a run whose state stays on a GPU: :func:`device_plan`) the host holds
    neither the integrator's copy nor the packed records (the device's are counted by
    :func:`device_memory`)."""
    d = dim
    state = state_bytes(d, strength_width, hourglass)
    # x, v, rho, e, the deviator's six components, plastic work, material state
    kept = strength_width if state_kept is None else state_kept
    integrator = 16 * d + 72 + 8 * kept + (8 * d if hourglass else 0)
    # a snapshot's copies (Simulation._snapshot_fields): the state's arrays, the views of
    # one number copied whole (a switch's factor and memory, the added masses), the pressure,
    # the von Mises stress and the common material state's columns again
    snapshot = state + 24 + 8 + 8 + 8 * CARRIED
    if gpu_state:  # (the step and the records are the device's)
        integrator = 0
    # without a switch the state's viscosity factor and memory are views of one number
    per_particle = state + (16 if switched else 0) + integrator + snapshots * snapshot
    # drho, de, de_visc, the deviator's rate (six components), pair count; dv; a correction's
    # books (its power and heating)
    buffers = 76 + 8 * d + (8 * d if contact else 0) + (16 if corrected else 0) \
        + (8 * d + 8 * d * d if hourglass else 0)
    # the CPU's rows, unpadded; the viscous acceleration's columns where a pass reads them
    # (a correction or a switch: CpuRates.record_columns)
    layout = record_columns(d, correction_matrix=force_correction and d > 1,
                            work_velocity=compatible, viscosity_factor=switched)
    records = 0 if gpu_state else 8 * layout["columns" if corrected or switched else "u"]
    ghost_arrays = (16 * d + 112) if walls else 0  # x, v, rho, e, S, m, h, material, body
    # the passes' copy of the common material state and a switch's factor and memory: the
    # extended rows' with walls, the particles' with a switch (else they read the state's own)
    carried = 8 * PASS_CARRIED if walls or switched else 0
    if walls:  # the state's integrated fields are the extended rows (Solver._allocate)
        per_particle -= 16 * d + 88
        if not switched:
            per_particle -= 8 * strength_width
            carried = 8 * strength_width
    # offsets, order, reference, the 2D and 3D rows' splits and the inner list's ends (each
    # built as 8 B, kept as 4); the build's temporaries (cell keys, sort order, sorted
    # positions, the cells' counts)
    neighbour_list = 12 + 4 * d + (8 if d > 1 else 0) + 24 + 8 * d + (8 if inner_list else 0)
    if compatible:  # the work pass's rate buffers, the pair energy rates, the velocities
        buffers += (76 + 8 * d) + 8 + 16 * d
    per_row = buffers + records + ghost_arrays + carried + neighbour_list + 4 * neighbours
    total = n * per_particle + (n + ghosts) * per_row + history_values * HISTORY_VALUE_BYTES
    return BASE_MEMORY + MEMORY_SAFETY * total


def available_memory() -> int | None:
    """Bytes of memory this process can still use: ``MemAvailable`` of ``/proc/meminfo`` (free
    memory plus what the kernel can reclaim), else ``os.sysconf``'s free pages; capped by the
    cgroup (container) limit less its usage where there is one.  None where unknown."""
    available = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if available is None:
        try:
            available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return None
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            used = int(Path("/sys/fs/cgroup/memory.current").read_text())
            available = min(available, max(0, int(limit) - used))
    except (OSError, ValueError):
        pass
    return available


def _pair_rate_key(device: str, dim: int, stretch: bool = False) -> str:
    import numba

    return (f"{device}-{dim}d-{numba.config.NUMBA_NUM_THREADS}threads"
            + ("-stretch" if stretch else ""))


def _pair_rate_path() -> Path:
    from .codegen import cache_directory

    return cache_directory() / PAIR_RATE_FILE


def pair_rate(device: str, dim: int, stretch: bool = False) -> tuple[float, str]:
    """Pair evaluations per second for runs of dimension ``dim`` on ``device`` with this many
    numba threads, with a kernel that follows the stretch or not (``stretch``): the rate the
    last run of that kind measured on this machine (stored by :func:`record_pair_rate`),
    else that of a run with the other kernel times or over :data:`STRETCH_COST`; else, for a
    2D or 3D case whose dimension has no rate yet, the other dimension's (a pair costs about
    the same in the two: the lattices' 1.15e8 and 1.14e8 pairs/s of 2026-12-06,
    benchmarks/README.md); else :data:`DEFAULT_PAIR_RATE` (:data:`DEFAULT_GPU_PAIR_RATE` on
    a GPU); and where it comes from."""
    try:
        stored = json.loads(_pair_rate_path().read_text())
    except (OSError, ValueError):
        stored = {}
    # the other kind's rate, as this kind's: a stretching run's is STRETCH_COST times slower
    borrowed = 1.0 / STRETCH_COST if stretch else STRETCH_COST
    dims = (dim, 5 - dim) if dim in (2, 3) else (dim,)
    for run_dim in dims:
        for kind, factor in ((stretch, 1.0), (not stretch, borrowed)):
            try:
                entry = stored[_pair_rate_key(device, run_dim, kind)]
                rate = float(entry["rate"]) * factor
                if rate > 0 and math.isfinite(rate):
                    where = "" if run_dim == dim else f" in {run_dim}D"
                    kernel = "a fixed kernel" if stretch else "a kernel that follows the stretch"
                    other = "" if kind == stretch else (
                        f" with {kernel}, its rate {'over' if stretch else 'times'} "
                        f"{STRETCH_COST}")
                    none = "" if run_dim == dim else f"; no {dim}D run has measured one"
                    return rate, (f"(measured on this machine by a run of {entry['case']!r}"
                                  f"{where}, {entry['date']}{other}{none})")
            except (KeyError, ValueError, TypeError):
                pass
    return (DEFAULT_GPU_PAIR_RATE if device == "gpu" else DEFAULT_PAIR_RATE,
            "(a conservative default: no run on this machine has measured one)")


def record_pair_rate(summary: dict[str, Any], name: str, stretch: bool = False) -> None:
    """Keep the pair rate a finished run measured (its summary's ``pair_evaluations`` over
    its ``wall_seconds`` less its ``compile_seconds``, numba's compiling and loading of code,
    and less :data:`STEP_SECONDS` a step) for later estimates, if it
    evaluated at least :data:`MIN_PAIRS_TO_RECORD` pairs and kept its thread count (a run
    whose thread governor gave up cores to other processes, ``thread_changes``, measured a
    loaded machine, not this one: :mod:`impactsph.threads`); kept apart for runs whose
    kernel follows the stretch (``stretch``).  Never fails a run."""
    pairs = summary.get("pair_evaluations") or 0
    wall = (summary.get("wall_seconds") or 0.0) - (summary.get("compile_seconds") or 0.0)
    if pairs < MIN_PAIRS_TO_RECORD or not wall > 0 or summary.get("thread_changes"):
        return
    # the pairs' own rate: the fixed cost of the steps (STEP_SECONDS) taken out, at most half
    rate = pairs / max(wall - (summary.get("n_steps") or 0) * STEP_SECONDS, 0.5 * wall)
    from . import atomic

    try:
        path = _pair_rate_path()
        try:
            data = json.loads(path.read_text())
            if not isinstance(data, dict):
                data = {}
        except (OSError, ValueError):
            data = {}
        data[_pair_rate_key(str(summary.get("device", "cpu")),
                            int(summary.get("dimension", 0)), stretch)] = {
            "rate": float(rate), "case": name, "n_particles": summary.get("n_particles"),
            "date": datetime.date.today().isoformat()}
        atomic.write_text(path, json.dumps(data, indent=1, sort_keys=True))
    except OSError:
        pass


def history_values(case: Case, steps: int) -> int:
    """Numbers a run of ``steps`` steps keeps in its history (a row every
    ``output.history_every`` steps: time, step, dt, 6 energies, the plastic work, the
    momentum, the external impulse with walls or clamps, the contact forces with walls or
    several bodies, and with several bodies 3 energies per body), its probes (every step: the
    time and each probe's velocity) and its gauges (every step: the time and each gauge's
    columns, at most 3 d + 13 each: held as numpy rows, about 8 bytes a number, but counted
    at the history's rate, which errs high)."""
    d, bodies = case.dimension, len(case.bodies)
    supported = bool(case.boundaries) or any(b.clamped is not None for b in case.bodies)
    contact = bodies * d if bodies > 1 else (d if case.boundaries else 0)
    columns = 10 + d + (d if supported else 0) + contact + (3 * bodies if bodies > 1 else 0)
    rows = steps // case.output.history_every + 1
    probes = (1 + d * len(case.output.probes)) if case.output.probes else 0
    gauges = (1 + (3 * d + 13) * len(case.output.gauges)) if case.output.gauges else 0
    return rows * columns + (steps + 1) * probes + (steps + 1) * gauges


def initial_time_step(case: Case, *, cfl_only: bool = False) -> float:
    """The CFL step of eq 26 at t = 0, ``courant * min h / (c + |v|)`` over the bodies (a tip
    mass's velocity counted at its arrival speed, an upper bound), and in the
    total-Lagrangian formulation at most its hourglass penalty's step
    (:func:`impactsph.tl_solver.lattice_hourglass_step`; ``cfl_only``: eq 26 alone)."""
    from .materials import resolve_material

    dt = math.inf
    for b, body in enumerate(case.bodies):
        mat = resolve_material(body.material, case.materials[body.material])
        c = math.sqrt(mat.wave_modulus(case.time.wave_speed) / mat.density)
        speed = max_speed(body, case.dimension)
        if body.tip_mass is not None:
            speed = max(speed, float(np.linalg.norm(body.tip_mass.velocity)))
        h = case.h_over_dx_of(b) * body_spacing(body.geometry)
        dt = min(dt, case.time.courant * h / (c + speed))
        if (case.formulation == "total_lagrangian" and case.stabilisation.tl_hourglass > 0.0
                and not cfl_only):
            from .tl_solver import lattice_hourglass_step  # its penalty's own limit

            dt = min(dt, lattice_hourglass_step(
                case.dimension, body_spacing(body.geometry), h,
                case.stabilisation.tl_hourglass, mat.youngs_modulus, mat.density,
                case.stabilisation.tl_hourglass_damping))
    return dt


def state_width(case: Case) -> int:
    """Columns of the case's material state (:meth:`TableLayout.state_width_of`)."""
    from .materials import TableLayout, case_materials

    materials = case_materials(case)
    return TableLayout.registered().state_width_of([m.model for m in materials],
                                                   [m.damage for m in materials])


def reference_run(case: Case, figures: bool | None = None) -> Any:
    """The viscosity of the reference run that a run of ``case`` draws its figures beside
    (``output.reference_viscosity``), or None: none given, the figures off (``figures``, else
    the case's ``output.figures``), or the case's own scheme."""
    ref = case.output.reference_viscosity
    drawn = case.output.figures if figures is None else figures
    return ref if drawn and ref is not None and ref != case.viscosity else None


def _case_table(case: Case) -> np.ndarray:
    """The case's material table (:func:`impactsph.materials.material_table`)."""
    from .materials import case_materials, material_table

    return material_table(case_materials(case), case.time.wave_speed)


def _table_stage_options(case: Case, table: np.ndarray) -> Any:
    """:func:`case_stage_options` from the case's ``table``, built already."""
    from .integrate import stage_options

    return stage_options(table, case.two_dimensional == "plane_stress",
                         case.two_dimensional == "axisymmetric")


def case_stage_options(case: Case) -> Any:
    """The options of the passes' module whose stage the case's runs use
    (:func:`impactsph.integrate.stage_options`: its 2D model and its materials' models)."""
    return _table_stage_options(case, _case_table(case))


def state_kept(case: Case) -> int:
    """How many of the case's material state's columns its step keeps in the start copy
    (:func:`impactsph.integrate.state_kept_of_table`: those a model of its materials
    changes)."""
    from .integrate import state_kept_of_table

    table = _case_table(case)
    return state_kept_of_table(_table_stage_options(case, table), table)


def estimate(case: Case, counts: list[int], *, pairs_per_particle: float | None = None,
             ghosts: int = 0, cells: float = 0.0, table_bytes: int = 0,
             start: float = 0.0) -> Estimate:
    """Memory and run time of the case with ``counts`` particles per body; the pair
    evaluations per particle measured at t = 0 (:func:`particle_checks`) if given, else those
    of a full lattice; the pair rate of the device the run will use (:func:`device_plan`).
    A run on a GPU gets its GPU memory too
    (:func:`device_memory`; ``cells``: its neighbour build's grid, ``table_bytes``: its
    material table, both known once the particles are placed)."""
    from .models import VISCOSITY
    from .physics.options import PassOptions
    from .physics.rates import ViscositySettings

    plan = device_plan(case)
    dim = case.dimension
    n = sum(counts)
    weights = np.asarray(counts, dtype=np.float64) / max(n, 1)
    spacings = np.array([body_spacing(b.geometry) for b in case.bodies])
    # the kernel's support in units of each body's own spacing
    support = SUPPORT_RADIUS * np.array([case.h_over_dx_of(b) for b in range(len(counts))])
    # the list's radius is that of the largest h, plus the skin; with kernel.max_stretch the
    # largest h grows by up to that factor once any part of a body has stretched
    radius = (float((support * spacings).max()) * (1.0 + case.time.neighbour_skin)
              * case.kernel.max_stretch)
    neighbours = float(weights @ [lattice_neighbours(radius / dx, dim) for dx in spacings])
    if pairs_per_particle is None:
        pairs_per_particle = float(weights @ [lattice_neighbours(s, dim) for s in support])
    dt = initial_time_step(case)
    steps = max(1, math.ceil(case.time.end / dt * (1 - 1e-12)))
    if case.time.max_steps is not None:
        steps = min(steps, case.time.max_steps)
    corrected = VISCOSITY[case.viscosity.scheme].correction is not None
    memory = memory_estimate(
        n, dim, neighbours, ghosts=ghosts, corrected=corrected, walls=bool(case.boundaries),
        contact=bool(case.boundaries) or len(case.bodies) > 1,
        hourglass=case.stabilisation.hourglass > 0.0,
        force_correction=PassOptions.of_case(case).gradient_correction
        == "velocity_gradient_and_forces",
        strength_width=state_width(case), state_kept=state_kept(case),
        compatible=case.time.energy_update == "compatible",
        switched=VISCOSITY[case.viscosity.scheme].switch is not None,
        # (the CPU's list only: the device builds none)
        inner_list=plan.device == "cpu" and ViscositySettings.of(case.viscosity).inner_reach < 1,
        snapshots=len(case.output.snapshot_times),
        history_values=history_values(case, steps), gpu_state=plan.resident)
    runs = 1 if reference_run(case) is None else 2
    if start > 0.0:  # a restart: the steps left (its memory holds the whole history still)
        steps = max(0, math.ceil((case.time.end - start) / dt * (1 - 1e-12)))
    # the reference run's arrays are allocated while the run's are still held
    memory = BASE_MEMORY + runs * (memory - BASE_MEMORY)
    rate, source = pair_rate(plan.device, dim, stretch=_stretches(case))
    # the integrator's rate evaluations per step (and the compatible energy update's work
    # pass), and the fixed cost of a step
    passes = len(INTEGRATORS[case.time.integrator].WEIGHTS) + (
        1 if case.time.energy_update == "compatible" else 0)
    seconds = runs * steps * (passes * n * pairs_per_particle / rate + STEP_SECONDS)
    device = (device_memory(case, plan.resident, n, ghosts, neighbours, cells, table_bytes)
              if plan.device == "gpu" else None)
    return Estimate(particles={b.name: k for b, k in zip(case.bodies, counts, strict=True)},
                    neighbours=neighbours, pairs_per_particle=pairs_per_particle,
                    ghosts=ghosts, memory=memory, available=available_memory(), dt=dt,
                    steps=steps, pair_rate=rate, pair_rate_source=source, seconds=seconds,
                    runs=runs, dt_source="eq 26" if dt >= initial_time_step(case, cfl_only=True)
                    else "the hourglass penalty's limit", device_line=plan.line,
                    state_on_gpu=plan.resident, order_line=order_line(case, n), start=start,
                    **({} if device is None else {"device_memory": device[0],
                                                  "device_available": device[1],
                                                  "device_name": device[2]}))


def order_line(case: Case, n: int) -> str:
    """A line on the particles' numbering where it matters: a run that
    ``compute.particle_order = "auto"`` renumbers, or a 2D run of
    :data:`impactsph.problem.RENUMBER_FROM` particles or more held to ``"input"``; else
    empty."""
    from .problem import RENUMBER_FROM, renumbering_pays

    setting = case.compute.particle_order
    if setting == "auto" and renumbering_pays(case, n):
        return (f"particle order: the {n:,} particles renumbered in the neighbour list's order "
                f"(compute.particle_order = 'auto' for a 2D run of {RENUMBER_FROM:,} or more: "
                f"about 0.8 of the step's time at 1e6); the snapshots carry each one's number "
                f"as placed (input_index); 'input' keeps that numbering")
    if setting == "input" and renumbering_pays(case, n):
        return (f"note: compute.particle_order = 'input' numbers the {n:,} particles as the "
                f"bodies place them; 'cells' (or 'auto') renumbers them in the neighbour list's "
                f"order, the same results to round-off with each particle's input number in "
                f"the snapshots: the 2D Taylor bar's steps took 0.80-0.81 of their time so at "
                f"1e6 particles")
    return ""


def grid_cells(case: Case, position: np.ndarray) -> float:
    """Cells of a neighbour build's grid over ``position``: the bounding box in cells of the
    list's radius (the largest support, with the skin and the stretch's largest h)."""
    if position.shape[0] == 0:
        return 0.0
    spacings = np.array([body_spacing(b.geometry) for b in case.bodies])
    support = SUPPORT_RADIUS * np.array([case.h_over_dx_of(b) for b in range(len(spacings))])
    radius = (float((support * spacings).max()) * (1.0 + case.time.neighbour_skin)
              * float(case.kernel.max_stretch))
    extent = position.max(axis=0) - position.min(axis=0)
    return float(np.prod(np.floor(extent / radius) + 1.0))


@dataclass(frozen=True)
class DevicePlan:
    """Where a run of a case will go: ``device`` (``"gpu"`` where it asks for one, one is
    usable here and nothing in it runs on the CPU only; else ``"cpu"``, where
    :func:`impactsph.devices.select_backend` falls back), whether its state stays on the GPU
    (``resident``) and the preflight's ``line`` about it ("" for a case that asks for the
    CPU)."""

    device: str = "cpu"
    resident: bool = False
    line: str = ""


def device_plan(case: Case) -> DevicePlan:
    """The :class:`DevicePlan` of ``case`` (under numba's CUDA simulator, as without a GPU:
    a run there falls back to the CPU)."""
    if case.compute.device != "gpu":
        return DevicePlan()
    from . import gpu
    from .simulation import _cpu_only

    why = gpu.unavailable_reason() or _cpu_only(case)
    if why is not None:
        return DevicePlan(line=f"device: compute.device = 'gpu' but {why}; the run will use "
                               f"the CPU")
    from .gpu_step import resident_unsupported

    host = resident_unsupported(case)
    if host is not None:
        return DevicePlan("gpu", False, f"device: the GPU for the rates, the state on the host "
                                        f"between steps ({host}: copied to the GPU at each "
                                        f"evaluation)")
    return DevicePlan("gpu", True, "device: the GPU, the whole step there (the state stays on "
                                   "it)")


def device_memory(case: Case, resident: bool, n: int, ghosts: int, neighbours: float,
                  cells: float = 0.0, table_bytes: int = 0) -> tuple[float, int | None, str]:
    """``(bytes, free, name)``: the peak GPU memory of the run of ``n`` particles,
    ``ghosts`` wall ghosts and ``neighbours`` stored list entries a row on a GPU
    (:class:`impactsph.gpu_memory.DeviceLayout`'s arrays: the whole step's where its state
    stays there, ``resident``, else the rates' alone; plus the list's indices once more,
    since a rebuild that outgrows them allocates the new before it frees the old; times
    :data:`GPU_MEMORY_SAFETY`, plus :data:`GPU_BASE_MEMORY`), the GPU's free memory (None
    where the driver does not say) and its name."""
    from . import gpu
    from .gpu_memory import DeviceLayout

    layout = DeviceLayout.of_case(case, threads_per_block=gpu.launch_settings()[0])
    entries = (n + ghosts) * neighbours
    if resident:
        arrays = layout.bytes(n, ghosts, entries, cells, table_bytes=table_bytes,
                              probes=len(case.output.probes), gauges=len(case.output.gauges))
    else:  # (the host's pair counts: int32 where they fit, as RateBuffers makes them)
        arrays = sum(layout.host_path_parts(n, ghosts, entries,
                                            table_bytes=table_bytes).values())
    free, name = gpu.free_memory()
    return GPU_BASE_MEMORY + GPU_MEMORY_SAFETY * (arrays + 4 * entries), free, name


def memory_check(case: Case, est: Estimate) -> Finding | None:
    """The error for a memory estimate above the available memory (None if it fits, or if
    ``IMPACTSPH_SKIP_MEMORY_CHECK`` is set to a non-empty value other than 0), naming the
    field that sets the largest body's particle count, or ``time.end`` when the history is
    the larger part."""
    if est.available is None or est.memory <= est.available:
        return None
    if os.environ.get("IMPACTSPH_SKIP_MEMORY_CHECK", "") not in ("", "0"):
        return None
    history = est.runs * MEMORY_SAFETY * history_values(case, est.steps) * HISTORY_VALUE_BYTES
    hint = ""
    if history > 0.5 * (est.memory - BASE_MEMORY):
        where = "time.end"
        cause = (f"{est.steps:,} steps, whose history takes {_bytes(history)}; a larger "
                 f"output.history_every keeps less")
        if case.time.end > END_TIME_MAX:  # the likelier cause: a unit slip (the warning's)
            hint = f"; {_end_time_hint(case.time.end)}"
    else:
        b = int(np.argmax(list(est.particles.values())))
        where = _size_field(case, b)
        cause = f"{est.total:,} particles"
    value = _field_value(case, where)
    return Finding("error", where, (
        f"{where} = {value!r}: the run needs about {_bytes(est.memory)} of memory (an "
        f"estimate: {cause}); this machine has {_bytes(est.available)} available{hint}"))


def device_memory_check(case: Case, est: Estimate) -> Finding | None:
    """The error for a GPU memory estimate above the GPU's free memory (None if it fits, if
    the run keeps no state on a GPU, if the free memory is unknown, or if
    ``IMPACTSPH_SKIP_MEMORY_CHECK`` is set as for :func:`memory_check`), naming the field that
    sets the largest body's particle count."""
    if est.device_memory is None or est.device_available is None \
            or est.device_memory <= est.device_available:
        return None
    if os.environ.get("IMPACTSPH_SKIP_MEMORY_CHECK", "") not in ("", "0"):
        return None
    b = int(np.argmax(list(est.particles.values())))
    where = _size_field(case, b)
    value = _field_value(case, where)
    on_gpu = " with their state on the GPU" if est.state_on_gpu else ", their rates on the GPU"
    return Finding("error", where, (
        f"{where} = {value!r}: the run needs about {_bytes(est.device_memory)} of GPU memory "
        f"(an estimate: {est.total:,} particles{on_gpu}); the {est.device_name} has "
        f"{_bytes(est.device_available)} free; compute.device = \"cpu\" runs it on the CPU"))


# -- checks of the case's numbers --------------------------------------------------------------

def _scaled_hint(value: float, low: float, high: float,
                 units: tuple[tuple[str, float], ...]) -> str:
    """``'; did you mean 792 MPa = 7.92e+08?'`` for the first unit that brings ``value`` into
    ``[low, high]``, or ``''``."""
    for unit, factor in units:
        if low <= value * factor <= high:
            return f"; did you mean {_g(value)} {unit} = {value * factor:.3g}?"
    return ""


def magnitude_checks(case: Case) -> list[Finding]:
    """Warnings for values that are implausible in SI units (a likely unit slip)."""
    out: list[Finding] = []

    def warn(where: str, value: Any, text: str) -> None:
        out.append(Finding("warning", where, f"{where} = {value!r}: {text}"))

    for name, mat in case.materials.items():
        where = f"materials.{name}"
        lo, hi = DENSITY_RANGE
        if not lo <= mat.density <= hi:
            hint = _scaled_hint(mat.density, lo, hi, (("g/cm^3", 1e3),)) \
                if mat.density < lo else ""
            warn(f"{where}.density", mat.density,
                 f"implausible density for a solid, foams aside (SI: {_g(lo)} to {_g(hi)} "
                 f"kg/m^3){hint}")
        for key, label in (("youngs_modulus", "Young's modulus"),
                           ("shear_modulus", "shear modulus")):
            value = getattr(mat, key)
            lo, hi = MODULUS_RANGE
            if value is not None and not lo <= value <= hi:
                hint = _scaled_hint(value, lo, hi, (("GPa", 1e9), ("MPa", 1e6))) \
                    if value < lo else ""
                warn(f"{where}.{key}", value, f"implausible {label} (SI: {_g(lo)} to "
                                              f"{_g(hi)} Pa){hint}")
        sigma = getattr(mat, "yield_stress", None)
        if isinstance(sigma, int | float) and sigma < YIELD_STRESS_MIN:
            hint = _scaled_hint(sigma, YIELD_STRESS_MIN, MODULUS_RANGE[1],
                                (("MPa", 1e6), ("GPa", 1e9)))
            warn(f"{where}.yield_stress", sigma,
                 f"implausibly low yield stress (SI, Pa: under {_g(YIELD_STRESS_MIN)}){hint}")
    out.extend(unused_viscosity_fields(case))
    out.extend(unused_material_fields(case))
    rigid = any(wall.type != "symmetry" for wall in case.boundaries)
    if (case.two_dimensional == "plane_stress" and rigid and case.contact.traction == "pressure"
            and case.contact.wall_layer == 0.0):
        warn("contact.traction", case.contact.traction,
             "in plane stress the pressure is a third of the in-plane stresses' sum, so a wall "
             "pushing with it alone lets a yielding body through (the 2D Taylor bar: 13,870 "
             "wall constraint events, energy error 3.7%); use traction = 'normal_stress' or a "
             "wall_layer > 0 (the defaults)")
    lo, hi = LENGTH_RANGE
    for b, body in enumerate(case.bodies):
        g, where = body.geometry, f"bodies.{b}.geometry"
        lengths: list[tuple[str, Any, float, float]] = []  # field, value, smallest, largest
        if isinstance(g, Block):
            lengths.append(("size", g.size, min(g.size), max(g.size)))
        elif isinstance(g, Disk | Cylinder | Sphere):
            lengths.append(("radius", g.radius, g.radius, g.radius))
            if isinstance(g, Cylinder):
                lengths.append(("length", g.length, g.length, g.length))
        for key, value, smallest, largest in lengths:
            if largest > hi:
                warn(f"{where}.{key}", value, f"{_g(largest)} m is large for an impact "
                     f"specimen (over {_g(hi)} m); did you mean mm = {largest * 1e-3:.3g} m?")
            elif smallest < lo:
                warn(f"{where}.{key}", value, f"{_g(smallest)} m is implausibly small (under "
                     f"{_g(lo)} m; SI lengths are in m)")
        if isinstance(g, Block):  # a spacing from count is size / count: size is checked
            spacing = max(g.spacings()) if g.spacing is not None else None
        else:
            spacing = g.spacing
        if spacing is not None and spacing > hi:
            warn(f"{where}.spacing", g.spacing, f"a spacing of {_g(spacing)} m is large "
                 f"(over {_g(hi)} m); did you mean mm = {spacing * 1e-3:.3g} m?")
        for key, velocity, speed in (
                ("velocity", body.velocity, max_speed(body, case.dimension)),
                ("tip_mass.velocity", body.tip_mass and body.tip_mass.velocity,
                 float(np.linalg.norm(body.tip_mass.velocity)) if body.tip_mass else 0.0)):
            if velocity and speed > SPEED_MAX:
                warn(f"bodies.{b}.{key}", velocity,
                     f"a speed of {_g(speed)} m/s is beyond "
                     f"hypervelocity impact ({_g(SPEED_MAX)} m/s); velocities are in m/s")
    if case.time.end > END_TIME_MAX:
        warn("time.end", case.time.end, _end_time_hint(case.time.end))
    # (a case shortened with --set time.end keeps its snapshot times)
    late = [t for t in case.output.snapshot_times if t > case.time.end * (1 + 1e-9)]
    if late:
        warn("output.snapshot_times", case.output.snapshot_times,
             f"{len(late)} of {len(case.output.snapshot_times)} after time.end = "
             f"{case.time.end!r}: no snapshot is taken then, nor any figure drawn from one "
             f"(a deformed shape, a profile)")
    return out


def _end_time_hint(end: float) -> str:
    """What an end time above :data:`END_TIME_MAX` probably meant (a unit slip)."""
    return (f"more than {_g(END_TIME_MAX)} s of simulated time for an impact (micro- to "
            f"milliseconds); did you mean {_g(end)} ms = {end * 1e-3:.3g} or {_g(end)} us = "
            f"{end * 1e-6:.3g}?")


def unused_material_fields(case: Case) -> list[Finding]:
    """A warning for each field of a material that belongs to a model it does not use: a
    ``yield_stress`` with ``model = "elastic"`` (a user who forgot to switch the model runs
    an elastic body), a ``[materials.X.mie_gruneisen]`` table with ``eos = "linear"``, a
    ``[materials.X.johnson_cook_damage]`` table with ``damage = "none"``.  The case table
    holds every registered model's fields, so such a field is accepted, and has no effect."""
    from .config import Material, model_keys
    from .library import material_fields
    from .models import DAMAGE, EOS, STRENGTH
    from .models.registry import Parameters

    owner: dict[str, tuple[str, str]] = {}  # a model's field or table -> (kind, model)
    for kind, registry in (("model", STRENGTH), ("eos", EOS), ("damage", DAMAGE)):
        for model in registry:
            for key in model_keys(model):
                if key not in Material.model_fields:  # (a common field: every model's)
                    owner.setdefault(key, (kind, model.name))
    out = []
    for name, mat in case.materials.items():
        # (what a library material brings, the case cannot leave out: not warned about)
        supplied = set(material_fields(mat.library)) if mat.library else set()
        chosen = {"model": mat.model, "eos": mat.eos, "damage": mat.damage}
        used = {key for model in (STRENGTH[mat.model], EOS[mat.eos], DAMAGE[mat.damage])
                for key in model_keys(model)}
        for key in sorted(mat.model_fields_set - used - supplied):
            if key not in owner:
                continue
            kind, model = owner[key]
            value = getattr(mat, key)
            shown = (f"materials.{name}.{key} = {value!r}" if not isinstance(value, Parameters)
                     else f"materials.{name}.{key}")
            what = "the table" if isinstance(value, Parameters) else "a parameter"
            out.append(Finding("warning", f"materials.{name}.{key}", (
                f"{shown}: {what} of {kind} = {model!r}, and this material's {kind} is "
                f"{chosen[kind]!r}; it has no effect")))
    return out


def unused_viscosity_fields(case: Case) -> list[Finding]:
    """A warning for each ``[viscosity]`` field the case sets that its scheme does not read
    (``limiter`` with ``scheme = "av"``, say): the case table holds every scheme's fields,
    so such a field is accepted, and has no effect.  (AC's ``alpha1`` and ``alpha2`` are
    its parameters, accepted and not read, so that a case switched from AV keeps its table
    without a warning: the README's ``impactsph run bars --set viscosity.scheme=ac``.)"""
    from .models import VISCOSITY

    out = []
    for where, viscosity in (("viscosity", case.viscosity),
                             ("output.reference_viscosity", case.output.reference_viscosity)):
        if viscosity is None:
            continue
        parameters = VISCOSITY[viscosity.scheme].parameters
        known = set(parameters.model_fields) if parameters is not None else set()
        for name in sorted(viscosity.model_fields_set - known - {"scheme"}):
            out.append(Finding("warning", f"{where}.{name}", (
                f"{where}.{name} = {getattr(viscosity, name)!r}: not a parameter of "
                f"scheme {viscosity.scheme!r} ({', '.join(sorted(known)) or 'none'}); it has "
                "no effect")))
    return out


def _steps_check(case: Case, est: Estimate) -> list[Finding]:
    unbounded = math.ceil(case.time.end / est.dt)
    if unbounded > STEPS_MAX and (case.time.max_steps is None
                                  or case.time.max_steps > STEPS_MAX):
        return [Finding("warning", "time.end", (
            f"time.end = {case.time.end!r}: about {unbounded:.3g} steps of dt = "
            f"{est.dt:.3g} s (eq 26), more than {STEPS_MAX:.0e}; is the end time right?"))]
    return []


# -- checks of the particles at t = 0 -----------------------------------------------------------

def _where(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in x) + "]"


def particle_checks(case: Case, problem: Any) -> tuple[list[Finding], np.ndarray, int]:
    """Errors and warnings about the particles of a built problem at t = 0, the pair
    evaluations of each particle (neighbours within the kernel support, as the pair loop
    counts them), and the number of wall ghosts."""
    from .boundaries import walls_of
    from .neighbours import NeighbourList

    s = problem.state
    n, dim = s.n, s.dim
    out: list[Finding] = []
    names = problem.body_names
    spacing_of_body = np.array([body_spacing(b.geometry) for b in case.bodies])
    dx = spacing_of_body[s.body]
    h = s.smoothing_length
    # one particle bodies
    per_body = np.bincount(s.body, minlength=len(names))
    for b in np.flatnonzero(per_body == 1):
        out.append(Finding("warning", f"bodies.{b}.geometry", (
            f"bodies.{b}.geometry: body {names[b]!r} has one particle: a body needs many "
            f"particles across it for its stress to be resolved")))
    # particle files: coordinates written in mm
    for b, body in enumerate(case.bodies):
        if isinstance(body.geometry, ParticleFile):
            x = s.position[s.body == b]
            extent = float(np.max(x.max(axis=0) - x.min(axis=0)))
            if extent > LENGTH_RANGE[1]:
                where = f"bodies.{b}.geometry.path"
                out.append(Finding("warning", where, (
                    f"{where} = {body.geometry.path!r}: the particles span {_g(extent)} m, more "
                    f"than {_g(LENGTH_RANGE[1])} m for an impact specimen; were the "
                    f"coordinates written in mm? (then {_g(extent * 1e-3)} m)")))
    # walls: particles behind a plane at t = 0
    walls = walls_of(case.boundaries, dim)
    if case.formulation == "total_lagrangian" and len(walls):  # its walls' push (PC-4)
        from .physics.penalty_contact import contact_diameters
        from .tl_solver import wall_start_overlap

        diameter = contact_diameters(s.mass, s.material, problem.table, dim,
                                     case.contact.penalty_distance)
        message = wall_start_overlap(s.position, s.body, diameter, walls.points,
                                     walls.normals)
        if message is not None:
            out.append(Finding("error", message.split(":", 1)[0], message))
    ghosts = 0
    reach = SUPPORT_RADIUS * float(h.max()) * (1.0 + case.time.neighbour_skin)
    for w in range(len(walls)):
        d = (s.position - walls.points[w]) @ walls.normals[w]
        ghosts += int(np.count_nonzero((d >= 0.0) & (d < reach)))
        behind = d < 0.0
        for b in np.flatnonzero(np.bincount(s.body[behind], minlength=len(names))):
            sel = behind & (s.body == b)
            out.append(Finding("error", f"boundaries.{w}", (
                f"boundaries.{w}: {int(sel.sum()):,} of the {int(per_body[b]):,} particles of "
                f"body {names[b]!r} (bodies.{b}) start behind the wall (down to "
                f"{_g(float(-d[sel].min()))} m; the normal {case.boundaries[w].normal} points "
                f"into the material): the run would stop at its first step")))
    # pairs: a neighbour list of radius 2 h_max (at least the overlap distance)
    radius = max(SUPPORT_RADIUS * float(h.max()), OVERLAP_SPACINGS * float(dx.max()))
    counts = np.zeros(n, dtype=np.int64)
    overlaps: dict[tuple[int, int], list] = {}
    duplicates: dict[int, list] = {}
    if n > 1:
        nl = NeighbourList.build(s.position, radius)
        order = nl.order.astype(np.int64)
        row_len = np.diff(nl.offsets)
        budget = 250_000  # pairs per chunk: temporaries of about 20 MB
        cuts = np.unique(np.concatenate([
            np.searchsorted(nl.offsets, np.arange(0, nl.n_pairs, budget), side="right") - 1,
            [n]]))
        for p0, p1 in zip(cuts[:-1], cuts[1:], strict=True):
            lo, hi = int(nl.offsets[p0]), int(nl.offsets[p1])
            i = np.repeat(order[p0:p1], row_len[p0:p1])
            j = order[nl.indices[lo:hi]]
            r = np.sqrt(np.sum((s.position[i] - s.position[j]) ** 2, axis=1))
            inside = (r > 0.0) & (r < SUPPORT_RADIUS * 0.5 * (h[i] + h[j]))
            counts += np.bincount(i[inside], minlength=n)
            first = i < j
            close = first & (r < OVERLAP_SPACINGS * np.minimum(dx[i], dx[j]))
            other = close & (s.body[i] != s.body[j])
            if other.any():
                bi, bj = s.body[i[other]], s.body[j[other]]
                a, b_ = np.minimum(bi, bj), np.maximum(bi, bj)
                for key in set(zip(a.tolist(), b_.tolist(), strict=True)):
                    sel = (a == key[0]) & (b_ == key[1])
                    k = int(np.argmin(r[other][sel]))
                    entry = overlaps.setdefault(key, [0, math.inf, None])
                    entry[0] += int(sel.sum())
                    if r[other][sel][k] < entry[1]:
                        entry[1], entry[2] = float(r[other][sel][k]), i[other][sel][k]
            dup = first & (s.body[i] == s.body[j]) & (r <= DUPLICATE_SPACINGS * dx[i])
            if dup.any():
                for b in np.unique(s.body[i[dup]]).tolist():
                    sel = s.body[i[dup]] == b
                    entry = duplicates.setdefault(b, [0, n])
                    entry[0] += int(sel.sum())
                    entry[1] = min(entry[1], int(j[dup][sel].min()))
    for (a, b), (pairs, closest, i) in sorted(overlaps.items()):
        out.append(Finding("warning", f"bodies.{b}.geometry", (
            f"bodies.{b}.geometry: body {names[b]!r} overlaps body {names[a]!r} "
            f"(bodies.{a}): {_plural(pairs, 'particle pair')} closer than {OVERLAP_SPACINGS} "
            f"spacing "
            f"(the closest {_g(closest)} m apart, at {_where(s.position[i])}); the bodies "
            f"start interpenetrated")))
    offset = np.concatenate([[0], np.cumsum(per_body)])
    for b, (pairs, j) in sorted(duplicates.items()):
        g = case.bodies[b].geometry
        where = f"bodies.{b}.geometry" + (".path" if isinstance(g, ParticleFile) else "")
        out.append(Finding("warning", where, (
            f"{where}: {_plural(pairs, 'pair')} of particles of body {names[b]!r} share a "
            f"position "
            f"(first: particle {int(j - offset[b])} at {_where(s.position[j])}); the pair loop "
            f"skips coincident particles, so they never push each other apart")))
    # neighbours within the kernel support
    need = MIN_NEIGHBOURS[dim]
    best = np.zeros(len(names), dtype=np.int64)
    np.maximum.at(best, s.body, counts)
    few = [b for b in range(len(names)) if per_body[b] > 1 and best[b] < need]
    # a width below 1 is the likely cause: said of the field that set it (the kernel's, once
    # for every body that takes it; else the body's own)
    narrow = [b for b in few if case.h_over_dx_of(b) < 1.0]
    by_kernel = [b for b in narrow if case.bodies[b].h_over_dx is None]
    if by_kernel:
        listed = ", ".join(f"{names[b]!r} {int(best[b])}" for b in by_kernel)
        out.append(Finding("warning", "kernel.h_over_dx", (
            f"kernel.h_over_dx = {case.kernel.h_over_dx!r}: too few neighbours within the "
            f"kernel support 2h at t = 0 (most of any particle, by body: {listed}); the cubic "
            f"spline needs about {need} in {dim}D (h_over_dx >= 1 on a lattice)")))
    for b in few:
        own = case.bodies[b].h_over_dx
        field = "kernel.h_over_dx" if own is None else f"bodies.{b}.h_over_dx"
        if b in narrow and own is not None:
            out.append(Finding("warning", field, (
                f"{field} = {own!r}: too few neighbours within the kernel support 2h at t = 0 "
                f"(most of any particle of body {names[b]!r}: {int(best[b])}); the cubic "
                f"spline needs about {need} in {dim}D (h_over_dx >= 1 on a lattice)")))
        elif b not in narrow:
            out.append(Finding("warning", f"bodies.{b}.geometry", (
                f"bodies.{b}.geometry: no particle of body {names[b]!r} has more than "
                f"{int(best[b])} neighbours within the kernel support 2h at t = 0; the cubic "
                f"spline needs about {need} in {dim}D: the body is too thin or too sparse for "
                f"its spacing ({field} = {case.h_over_dx_of(b)!r})")))
    for b in range(len(names)):
        if per_body[b] < 2 or best[b] == 0:  # one particle, or all isolated: said above
            continue
        alone = np.flatnonzero((s.body == b) & (counts == 0))
        if alone.size:
            g = case.bodies[b].geometry
            where = f"bodies.{b}.geometry" + (".path" if isinstance(g, ParticleFile) else "")
            out.append(Finding("warning", where, (
                f"{where}: {_plural(alone.size, 'particle')} of body {names[b]!r} "
                f"{'has' if alone.size == 1 else 'have'} no neighbour "
                f"within the kernel support 2h at t = 0 (first: particle "
                f"{int(alone[0] - offset[b])} at {_where(s.position[alone[0]])}): "
                f"{'it' if alone.size == 1 else 'they'} will not interact")))
    return out, counts, ghosts


# -- the whole check ---------------------------------------------------------------------------

def preflight(case: Case, start: float = 0.0) -> Report:
    """Count, estimate and check a validated case (see the module docstring).  A memory
    refusal is returned as the report's only error, before any particle is placed; the
    other checks build the particles (:func:`impactsph.problem.build_problem`, which raises
    :class:`~impactsph.errors.CaseError` for a set-up it cannot make)."""
    from .problem import build_problem

    counts = count_particles(case)
    est = estimate(case, counts)
    refusal = memory_check(case, est) or device_memory_check(case, est)
    if refusal is not None:
        return Report(est, [refusal])
    findings = magnitude_checks(case)
    problem = build_problem(case)
    particle_findings, pairs, ghosts = particle_checks(case, problem)
    n = problem.state.n
    est = estimate(case, counts, pairs_per_particle=float(pairs.sum()) / max(n, 1),
                   ghosts=ghosts, cells=grid_cells(case, problem.state.position),
                   table_bytes=int(problem.table.nbytes), start=start)
    refusal = memory_check(case, est) or device_memory_check(case, est)
    findings = [*([refusal] if refusal else []), *particle_findings, *findings,
                *_steps_check(case, est)]
    findings.sort(key=lambda f: f.level != "error")
    return Report(est, findings)


def check_case(case: Case, start: float = 0.0) -> Report:
    """:func:`preflight` (``start``: a restart's time); raise
    :class:`~impactsph.errors.CaseError` with the first error's line (without its ``error:
    ``) if there is one."""
    report = preflight(case, start)
    if report.errors:
        raise CaseError(report.errors[0].message)
    return report


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def before_run(case: Case, quiet: bool = False,
               echo: Callable[[str], None] = _stderr, start: float = 0.0) -> Report:
    """What ``impactsph run`` does first: :func:`check_case`, its lines to ``echo`` (stderr;
    the warnings only if ``quiet``), then the :func:`compile_notice` if the kernels are not
    cached.  ``start``: a restart's checkpoint time, from which the run time is estimated
    (it was estimated from t = 0)."""
    report = check_case(case, start)
    for line in [f.line() for f in report.findings] if quiet else report.lines():
        echo(line)
    notice = compile_notice(case)
    if notice is not None:
        echo(notice)
    return report


# -- compilation ---------------------------------------------------------------------------------

def kernels_cached(case: Case) -> bool | None:
    """Whether numba's disk cache holds the generated passes the case's run uses (its pair
    pass, and the integrator's stage pass): False means the run compiles them first.  None
    where it cannot tell.  Without the stretch the pair pass may come from either module:
    the one of a single smoothing length (``PassOptions.uniform_h``, what most runs use) or
    the case's own (bodies of different h); either one cached counts."""
    from dataclasses import replace

    from .physics.options import PassOptions
    from .physics.rates import compiled_passes

    def cached(dispatcher) -> bool:
        return Path(dispatcher._cache._cache_file._index_path).is_file()

    try:
        options = PassOptions.of_case(case)
        modules = [options] + ([replace(options, uniform_h=True)]
                               if case.kernel.max_stretch <= 1.0 else [])
        pairs = any(cached(compiled_passes(case.dimension, options=o).pair_pass)
                    for o in modules)
        stage = case_stage_options(case)
        return pairs and cached(compiled_passes(case.dimension, options=stage).stage)
    except (AttributeError, OSError, TypeError):
        return None


def compile_notice(case: Case) -> str | None:
    """The line to show before a run that compiles the kernels (None if they are cached)."""
    if case.compute.device == "cpu" and kernels_cached(case) is False:
        return "compiling the SPH kernels for this machine (first run only, ~1 min)"
    return None


# -- after the run -------------------------------------------------------------------------------

def keeps_kinetic_energy(case: Case) -> bool:
    """Whether the case is expected to keep its kinetic energy: no material yields (elastic
    bodies rebound and vibrate), or nothing stops the body (one body, no wall, no clamp)."""
    from .models import STRENGTH

    dissipative = any(STRENGTH[m.model].return_map is not None for m in case.materials.values())
    held = bool(case.boundaries) or len(case.bodies) > 1 or any(
        b.clamped is not None for b in case.bodies)
    return not (dissipative and held)


def _stretches(case: Case) -> bool:
    """Whether the case's kernel follows the stretch (``kernel.max_stretch`` > 1, resolved)."""
    return case.kernel.max_stretch > 1.0


def after_run(case: Case, summary: dict[str, Any], restarted: bool = False,
              echo: Callable[[str], None] = _stderr) -> list[str]:
    """Warnings about a finished run, one line each to ``echo`` (stderr) and returned, and
    the pair rate it measured kept for later estimates (:func:`record_pair_rate`, its
    compiling left out; not for a run ``restarted`` from a checkpoint, whose pieces may have
    run on other machines or under other loads).  Warns when more than
    :data:`KINETIC_ENERGY_REMAINING` of the initial kinetic energy remains at the end time in
    a problem that is expected to dissipate it (:func:`keeps_kinetic_energy`), unless the
    case's analysis measures the impact part-way by design
    (:attr:`impactsph.problems.ProblemKind.ends_during_impact`: the plates)."""
    from .problems import get_problem

    if not restarted:
        record_pair_rate(summary, case.name, stretch=_stretches(case))
    lines = []
    ratio = summary.get("kinetic_energy_ratio_final")
    reached = summary.get("t_end", case.time.end) >= case.time.end * (1 - 1e-9)
    if (ratio is not None and ratio > KINETIC_ENERGY_REMAINING and reached
            and not keeps_kinetic_energy(case)
            and not get_problem(case.analysis).ends_during_impact):
        lines.append(f"warning: time.end = {case.time.end!r}: {100 * ratio:.3g}% of the "
                     f"initial kinetic energy remains at the end time: the impact may not be "
                     f"over; consider a longer time.end")
    for line in lines:
        echo(line)
    return lines
