"""The survey of the state, one particle at a time: its bad values, its CFL step (eq 26),
kinetic and internal energy and momentum, summed per chunk of :data:`SURVEY_CHUNK` particles
and the chunks folded in a fixed order (:func:`fold_survey`), so that the result does not
depend on the number of threads.

Two loops call these: :func:`impactsph.integrate._survey_kernel` (the survey on its own: at a
run's start, and after a callback that read the state) and the integrator's stage,
:func:`impactsph.physics.passes.stage` (the survey of each step's result in the step's last
stage, with no pass of its own).  Both chunk and fold alike, so they give the same bits.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numba.extending import overload

from impactsph.boundaries import plane_distance
from impactsph.materials import SHEAR, WAVE_MODULUS

#: Particles per work item of the survey's partial sums (and of the stage that surveys).
SURVEY_CHUNK = 256
#: The hourglass control (docs/stabilisation.md) stiffens and damps the grid-scale modes, so
#: with it the CFL step uses ``c + HOURGLASS_SPEED zeta c_shear`` for ``c``.  Measured on the
#: elastic Taylor bar (plane strain, zeta = 2, the gradient correction of the forces, AC): the
#: energy error stays at 1e-4 up to Courant 0.25 and grows to 10% at 0.3, and the beam is
#: stable at 0.3 with zeta = 1; 0.25 puts zeta = 2 at an effective Courant number of 0.23.
HOURGLASS_SPEED = 0.25
#: the survey's code for a particle behind a wall or symmetry plane (after the bad fields of
#: :func:`bad_field`, 0-5): ``BEHIND_WALL * n + i``
BEHIND_WALL = 6
#: the columns of a chunk's partial survey: the smallest ``h / (c + |v|)`` (s), kinetic and
#: internal energy (J) and momentum (N s, three components)
SURVEY_WIDTH = 6


@nb.njit(inline="always", cache=True)
def bad_field(i, x, v, rho, e, S):
    """The first bad field of particle ``i`` (0 position, 1 velocity, 2 density, 3 specific
    energy, 4 deviatoric stress: non-finite; 5 density: not positive), or -1 (the CPU's
    survey and the GPU's, :mod:`impactsph.gpu_step`, call this)."""
    pos_ok = True
    vel_ok = True
    for a in range(x.shape[1]):
        pos_ok = pos_ok and math.isfinite(x[i, a])
        vel_ok = vel_ok and math.isfinite(v[i, a])
    stress_ok = True
    for a in range(3):
        for b in range(3):
            stress_ok = stress_ok and math.isfinite(S[i, a, b])
    if not pos_ok:
        return 0
    if not vel_ok:
        return 1
    if not math.isfinite(rho[i]):
        return 2
    if not math.isfinite(e[i]):
        return 3
    if not stress_ok:
        return 4
    if not rho[i] > 0.0:
        return 5
    return -1


def _flat_rows(a, lo, hi):
    """The rows ``lo`` to ``hi - 1`` of ``a`` as one flat array (compiled code only: a view
    of a C-contiguous ``a``, a copy of any other)."""
    raise NotImplementedError("compiled code only")


@overload(_flat_rows, inline="always")
def _flat_rows_compiled(a, lo, hi):
    if a.layout == "C":
        return lambda a, lo, hi: a[lo:hi].reshape(-1)
    return lambda a, lo, hi: np.ascontiguousarray(a[lo:hi]).reshape(-1)


@nb.njit(inline="always", cache=True)
def rows_finite(lo, hi, x, v, rho, e, S):
    """Whether particles ``lo`` to ``hi - 1`` have no bad field (:func:`bad_field`): every
    position, velocity, density, specific energy and deviatoric stress finite and every
    density positive.  A flat loop a field, from zero, with no branch, which LLVM
    vectorises: 2.6 us for the Taylor bar's 1,407 particles, where :func:`bad_field` a
    particle took 16 us (2026-12-06).  A chunk for which this is true needs no
    :func:`bad_field` a particle (:func:`survey_particle`'s ``checked``)."""
    ok = True
    densities, energies = _flat_rows(rho, lo, hi), _flat_rows(e, lo, hi)
    for k in range(densities.shape[0]):
        ok &= (abs(densities[k]) < np.inf) & (abs(energies[k]) < np.inf) & (densities[k] > 0.0)
    stresses = _flat_rows(S, lo, hi)
    for k in range(stresses.shape[0]):
        ok &= abs(stresses[k]) < np.inf
    positions, velocities = _flat_rows(x, lo, hi), _flat_rows(v, lo, hi)
    for k in range(positions.shape[0]):
        ok &= (abs(positions[k]) < np.inf) & (abs(velocities[k]) < np.inf)
    return ok


#: a chunk's survey before its first particle (:func:`survey_particle`'s ``acc``)
SURVEY_START = (-1, np.inf, 0.0, 0.0, 0.0, 0.0, 0.0)


@nb.njit(inline="always", cache=True)
def survey_particle(i, n, x, v, rho_i, rho, e, S, m, inertia_i, h, material, table, hourglass,
                    points, normals, acc, checked):
    """Particle ``i`` (of ``n``) added to its chunk's survey ``acc = (first, step, KE, IE,
    p_x, p_y, p_z)`` (start: :data:`SURVEY_START`); returns the new ``acc``.  ``first``: the
    chunk's first bad code, ``field * n + i`` for the first particle of the first bad field
    (:func:`bad_field`; a particle with none that lies behind one of the planes ``points``,
    ``normals``, the walls and symmetry planes, is bad in field :data:`BEHIND_WALL`), or -1;
    ``step``: the smallest ``h / (c + |v|)`` (s).  ``rho_i``: the
    particle's material density (kg/m^3; ``rho`` itself carries a mass per area in plane
    stress and axisymmetry), from which its wave speed; ``inertia_i`` its mass and added mass,
    the inertia of the kinetic energy and momentum (kg), ``m`` that of the internal energy.
    The CPU's survey, its stage and the GPU's survey kernel (:mod:`impactsph.gpu_step`) call
    this.  With the hourglass
    control (``hourglass`` = zeta > 0) the signal speed adds :data:`HOURGLASS_SPEED` zeta times
    the shear wave speed.  ``checked``: the particle is known to have no bad field
    (:func:`rows_finite` of its chunk), so :func:`bad_field` is not asked."""
    first, step, ke, ie, p0, p1, p2 = acc
    dim = x.shape[1]
    speed2 = 0.0
    for a in range(dim):
        speed2 += v[i, a] * v[i, a]
    field = -1 if checked else bad_field(i, x, v, rho, e, S)
    if field < 0:
        for w in range(points.shape[0]):
            if plane_distance(x, i, points, normals, w) < 0.0:
                field = BEHIND_WALL
    if field >= 0:
        code = field * n + i
        if first < 0 or code < first:
            first = code
    c = math.sqrt(table[material[i], WAVE_MODULUS] / rho_i)
    if hourglass > 0.0:
        c += HOURGLASS_SPEED * hourglass * math.sqrt(table[material[i], SHEAR] / rho_i)
    step = min(step, h[i] / (c + math.sqrt(speed2)))
    ke += 0.5 * inertia_i * speed2
    ie += m[i] * e[i]
    p0 += inertia_i * v[i, 0]
    if dim > 1:
        p1 += inertia_i * v[i, 1]
    if dim > 2:
        p2 += inertia_i * v[i, 2]
    return first, step, ke, ie, p0, p1, p2


@nb.njit(inline="always", cache=True)
def store_survey(acc, parts, bad_of, chunk):
    """A chunk's survey ``acc`` (:func:`survey_particle`) into row ``chunk`` of ``parts``
    (:data:`SURVEY_WIDTH` columns) and ``bad_of``."""
    bad_of[chunk] = acc[0]
    parts[chunk, 0] = acc[1]
    parts[chunk, 1] = acc[2]
    parts[chunk, 2] = acc[3]
    parts[chunk, 3] = acc[4]
    parts[chunk, 4] = acc[5]
    parts[chunk, 5] = acc[6]


@nb.njit(inline="always", cache=True)
def fold_survey(parts, bad_of, n_chunks):
    """The first ``n_chunks`` chunks' partial surveys (rows of ``parts``) and first bad codes
    (``bad_of``), in chunk order, into the row after them: the smallest ``h / (c + |v|)``
    (s, before the Courant number), ``KE, IE, p_x, p_y, p_z`` and the first bad code, or
    -1."""
    step = np.inf
    bad = -1
    for k in range(1, SURVEY_WIDTH):
        parts[n_chunks, k] = 0.0
    for chunk in range(n_chunks):
        step = min(step, parts[chunk, 0])
        for k in range(1, SURVEY_WIDTH):
            parts[n_chunks, k] += parts[chunk, k]
        if bad_of[chunk] >= 0 and (bad < 0 or bad_of[chunk] < bad):
            bad = bad_of[chunk]
    parts[n_chunks, 0] = step
    bad_of[n_chunks] = bad


def folded_survey(parts: np.ndarray, bad_of: np.ndarray) -> tuple[float, np.ndarray, int]:
    """``(dt, sums, bad)`` from the folded row (the last) of ``parts`` and ``bad_of``
    (:func:`fold_survey`): ``dt`` before the Courant number, ``sums = (KE, IE, p_x, p_y,
    p_z)`` (a copy)."""
    return float(parts[-1, 0]), parts[-1, 1:].copy(), int(bad_of[-1])


@nb.njit(inline="always", cache=True)
def survey_chunks(n: int) -> int:
    """The chunks of a survey of ``n`` particles (at least one); the survey's arrays have a
    row more, for the folded result."""
    return max(1, (n + SURVEY_CHUNK - 1) // SURVEY_CHUNK)


@nb.njit(cache=True)
def fold_stage(n_active, walls, survey, surveyed, bad_of):  # pragma: no cover (compiled)
    """After every share of the integrator's stage of ``n_active`` particles
    (:func:`impactsph.physics.passes.stage`): its chunks' wall rows ``walls[chunk] = (moved,
    impulse)`` added in chunk order into the row after them, and with ``survey`` its chunks'
    surveys folded (:func:`fold_survey`)."""
    n_chunks = survey_chunks(n_active)
    for k in range(walls.shape[1]):
        walls[n_chunks, k] = 0.0
    for chunk in range(n_chunks):
        for k in range(walls.shape[1]):
            walls[n_chunks, k] += walls[chunk, k]
    if survey:
        fold_survey(surveyed, bad_of, n_chunks)
