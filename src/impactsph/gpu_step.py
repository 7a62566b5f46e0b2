"""The whole time step on the GPU: :class:`ResidentStep` keeps a run's state on the device
between steps (issue 16; docs/gpu.md, "The state on the device").

:class:`~impactsph.gpu.GpuRates` runs the rate passes on the GPU but takes the state up and
the rates back at every evaluation; at a million 3D particles those copies alone cost more than
the whole step should (docs/gpu.md).  Here the state, the step's start copy, the neighbour list
and the rates stay on the device, and a step is a sequence of kernel launches:

- the neighbour list's staleness test (the largest displacement since the build, one number
  back) and, when it is stale, its rebuild on the device: the bounding box, each particle's cell,
  a counting sort by cell (particles in ascending number within a cell, so the order does not
  depend on the threads' scheduling), then the same two sweeps as the CPU builder (count,
  prefix sum, store).  The stencil and the particles within a cell come in the CPU builder's
  order, and a 2D or 3D row is split at the support as the CPU's is, so each particle's neighbours
  are listed in the same order on both (but for the CPU's inner list, which the CPU holds as
  each row's first entries where a correction or switch reads it, and the device builds
  none); where the smoothing lengths differ (a body of its own
  ``h_over_dx``) each pair is kept within its own radius and split at its own support, as
  the CPU's list with a radius per pair;
- the rate passes of :func:`impactsph.physics.passes.cuda_kernels` on the device records;
- the integrator's stages with :func:`~impactsph.physics.passes.advance_particle` (the
  strength model's return map, damage and the plastic work included), the CPU stage's body;
- the survey (CFL step, kinetic and internal energy, momentum, the first bad value) and the
  powers booked for the history, as per-block partial sums that one thread then adds in block
  order: the same input gives the same bits, whatever the scheduling.

What comes back: one small record per step (the time step, energies, momentum, the first bad
value), one number per rate evaluation (the displacement test), a few at each rebuild (the
bounding box, the pair count), and the state itself only when something on the host asks for
it (a history row, a snapshot, a checkpoint, a callback; :class:`impactsph.simulation.Simulation`
downloads it lazily).  No physics is stated here: the kernels call the bodies that the CPU
passes call.

Rigid walls are handled on the device too: at each rebuild their ghosts are chosen (a count,
a prefix sum and a fill, in the order of :meth:`impactsph.boundaries.Walls.select`), at each
evaluation the ghosts' rows are filled from their sources
(:func:`impactsph.boundaries.fill_ghost`), and after each stage the walls' constraint acts
(:func:`impactsph.boundaries.enforce_particle`), its events and impulse booked as the CPU
books them; the walls' penalty layer (``contact.wall_layer``) adds its push to the rates
(:func:`impactsph.boundaries.layer_push_particle`).  The hourglass control and the Coulomb
friction between bodies run their rate kernels on the device state, in the CPU's order
(pairs, friction, correction, hourglass control, the walls' friction and then their
layer, each particle's own: :func:`impactsph.boundaries.friction_particle`,
``layer_push_particle``); clamped particles are
held by the stage (:func:`~impactsph.physics.passes.advance_particle`), and the supports'
impulse is booked from the step's mean accelerations (``clamp_sums``, ``clamp_finish``).
A viscosity switch keeps its factors and memories on the device: each evaluation's switch
kernel sets them for the next (at the evaluation's time, as
:meth:`impactsph.solver.Solver.rates`), and ``carry`` puts them, with the common material
state, into the passes' ``carried`` columns before the records are made.

Symmetry planes too: their ghosts are chosen after the rigid walls', plane by plane, each
plane's from every row so far (``plane_count``, a prefix sum, ``plane_list``, and the new
ghosts' positions for the next plane's search, ``ghost_position``): the stages of
:meth:`impactsph.boundaries.Walls.select`, in its order.  They are filled stage by stage (a
corner image after its source ghost), and after the pair kernel (and the correction
matrices' or a reconstructing viscosity's kernel) each stage's ghosts take their sources'
results mirrored (``mirror_results``, ``mirror_matrices``: the CPU's
:func:`impactsph.boundaries.mirror_ghost_results` and ``mirror_ghost_matrices``, a ghost a
thread).

Axisymmetry too: its axis is a symmetry plane, the stage's hoop terms are the CPU's, and
the survey and the walls' layer take each particle's material density and area per radian
as the CPU's do.  Driven regions: after each stage their particles take the prescribed
velocity (``drive``, the host evaluating its expression of t), and each step's reactions and
work are booked on the device (``clamp_sums`` over the region, ``drive_finish``), their
impulse on the host (the prescribed momentum change).  Added mass (a tip mass carried as
added inertia): the accelerations are scaled by ``m / (m + added)`` after the rates
(``scale``), and the survey, the books' impulses and the bodies' kinetic energy take the
inertia ``m + added``, as on the CPU.  Gauges take their particles' rows from the device at
each step (``gauge_rows``), as probes take their velocities.

The time integrators: Table 1's midpoint step and SSP-RK3 (the second and third stages
from their own start copy, ``kept``; the convex combinations by ``combine``, a particle of
the CPU's :func:`impactsph.integrate.combine_kept`; the step's mean acceleration and, with
several bodies, its mean contact force by ``weigh``).  Plane stress: the stage's secant
iteration on the thickness is the CPU's (:func:`~impactsph.physics.passes.advance_particle`
compiled with the case's options), and the survey reads the material density over the
thickness ratio.

The compatible energy update: after the corrector's stage, the work pass (``mean_velocity``,
the ghosts' mirror of it, ``work_columns`` into the corrector's records, the pair kernel into
outputs of its own, ``work_energy``), its heating booked instead of the corrector's, as
:meth:`impactsph.solver.Solver.work_rates` and the CPU's midpoint step.

A smoothing length that follows the stretch: at each rebuild, before the ghosts are chosen,
the CPU's neighbourhood fit over the old list (``stretch_rows``, the old ghosts' rows
mirrored stage by stage by ``stretch_mirror``, ``stretch``), then the support, skin and
radius from the largest h (``largest``), as :meth:`impactsph.solver.Solver._build`.

Which runs keep their state on the device: every updated-Lagrangian run (the
total-Lagrangian formulation runs on the CPU), unless ``compute.resident = false``:
:func:`resident_unsupported` names what would keep a run on the host path, where it
evaluates its rates on the GPU with the state on the host, and its log says why.
"""

from __future__ import annotations

import math
from functools import cache
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from . import boundaries, codegen, integrate
from .gpu import RECORD_ORDER, cuda, gpu_kernels, record_columns, simulator_enabled
from .gpu_memory import BUFFER_MARGIN, SCAN_CHUNK, DeviceLayout, arrays_of
from .kernels import SUPPORT_RADIUS
from .models.columns import (
    CARRIED,
    PASS_CARRIED,
    THICKNESS_RATIO,
    VISCOSITY_FACTOR,
    VISCOSITY_MEMORY,
)
from .physics import stress_rate, stretch, survey
from .physics.rates import compiled_passes

if TYPE_CHECKING:
    from .config import Case
    from .state import ParticleState

# SCAN_CHUNK: entries of a prefix sum that one thread adds serially (the sums of the chunks
# are summed the same way, recursively); BUFFER_MARGIN: the builds' kept arrays grow by
# 1/BUFFER_MARGIN more than they need (the list's indices are most of them: about 290 B a
# particle in 3D, 1/8 of it was 37 B).  Both from impactsph.gpu_memory, which counts them.
#: The survey's record: dt, KE, IE, p_x, p_y, p_z, bad (as a float).
SURVEY_WIDTH = 7
#: The books' columns: the viscous heating, the correction's work and its heating (each the
#: time integral, J), the pair evaluations, the walls' push's impulse (3, N s), the walls'
#: constraint's events and impulse (1 + 3), the step's mean push so far (3, N), the supports'
#: impulse on the clamped particles (3, N s).
TOTALS = 7
EVENTS = 7
LAST_PUSH = 11
CLAMP = 14
BOOKS_WIDTH = 17
#: The integrated fields of :class:`~impactsph.state.ParticleState`, in the order of the
#: device arrays.
INTEGRATED = ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
              "plastic_work", "material_state", "hourglass_acceleration")
#: The constant fields the kernels read (the added masses only through the inertia,
#: :meth:`ResidentStep.upload`).
CONSTANT = ("mass", "smoothing_length", "material", "body", "clamped", "initial_position")
#: The time integrators (``time.integrator``) whose steps :class:`ResidentStep` takes on the
#: device: Table 1's midpoint step and SSP-RK3 (:mod:`impactsph.integrate`).
DEVICE_INTEGRATORS = ("midpoint", "ssp_rk3")
#: A code above any bad-value code: none found.
NO_BAD = np.iinfo(np.int64).max


def resident_unsupported(case: Case) -> str | None:
    """Why the state of ``case`` cannot stay on the device between steps (None: it can)."""
    if not case.compute.resident:
        return "compute.resident = false"
    if case.formulation != "updated_lagrangian":
        return f"formulation = {case.formulation!r} runs on the host"
    if case.time.integrator not in DEVICE_INTEGRATORS:
        return f"time.integrator = {case.time.integrator!r} runs on the host"
    return None


# -- the kernels ---------------------------------------------------------------------------------
@cache
def step_kernels(dim: int, simulated: bool, version: int, options: Any, tpb: int):
    """The step's own kernels for dimension ``dim`` (the passes' module of ``options``,
    ``version``: the registries' version), ``tpb`` threads per block (the partial sums' block
    size): a namespace of CUDA kernels."""
    passes = compiled_passes(dim, simulated, options)
    advance_particle = passes.advance_particle
    # the walls' functions as the CPU runs them (their Python source under the simulator)
    fill_ghost = boundaries.fill_ghost.py_func if simulated else boundaries.fill_ghost
    mirror_ghost_result = (codegen._python_all_the_way(boundaries.mirror_ghost_result)
                           if simulated else boundaries.mirror_ghost_result)
    mirror_ghost_matrix = (codegen._python_all_the_way(boundaries.mirror_ghost_matrix)
                           if simulated else boundaries.mirror_ghost_matrix)
    SYMMETRY = boundaries.SYMMETRY  # noqa: N806 - a compile-time constant of the kernels
    enforce_particle = (boundaries.enforce_particle.py_func if simulated
                        else boundaries.enforce_particle)
    layer_push_particle = (codegen._python_all_the_way(boundaries.layer_push_particle)
                           if simulated else boundaries.layer_push_particle)
    friction_particle = (codegen._python_all_the_way(boundaries.friction_particle)
                         if simulated else boundaries.friction_particle)
    # the CPU's survey of one particle (its Python source, and that of what it calls, under
    # the simulator)
    survey_particle = (codegen._python_all_the_way(survey.survey_particle) if simulated
                       else survey.survey_particle)
    SURVEY_START = survey.SURVEY_START  # noqa: N806 - a compile-time constant of the kernels
    store_upper = stress_rate.store_upper.py_func if simulated else stress_rate.store_upper
    combine_particle = (integrate.combine_particle.py_func if simulated
                        else integrate.combine_particle)
    # a smoothing length that follows the stretch: the CPU's row of (ST-2, ST-3) and its
    # ghosts' mirrored rows
    stretch_row = (codegen._python_all_the_way(stretch.stretch_row) if simulated
                   else stretch.stretch_row)
    mirror_row = (codegen._python_all_the_way(stretch.mirror_row) if simulated
                  else stretch.mirror_row)
    DIM = dim  # noqa: N806 - a compile-time constant of the kernels
    TPB = tpb  # noqa: N806
    STENCIL = 3**dim  # noqa: N806
    BODY_WIDTH = 4 + dim  # noqa: N806 - energies, plastic work, force, displacement
    float64 = np.float64

    @cuda.jit
    def advance_kernel(n, dt, x0, v0, rho0, e0, S0, pw0, st0, hg0, v_rate, dv, drho, de, dS,
                       dhg, clamped, material, table, h, x, v, rho, e, S, pw, st, hg):
        i = cuda.grid(1)
        if i < n:
            advance_particle(i, dt, x0, v0, rho0, e0, S0, pw0, st0, hg0, v_rate, dv, drho, de,
                             dS, dhg, clamped, material, table, h, x, v, rho, e, S, pw, st, hg)

    @cuda.jit
    def start_kernel(n, x, v, rho, e, S, pw, st, hg, x0, v0, rho0, e0, S0, pw0, st0, hg0):
        """The step's start copy of the integrated fields (the advance's ``x0, v0, ...``),
        the deviator as its six components: one launch for what were seven copies and a
        launch (each about 0.2 ms of the host's time at a step's start, when the device waits
        for it: benchmarks/README.md)."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                x0[i, a] = x[i, a]
                v0[i, a] = v[i, a]
            rho0[i] = rho[i]
            e0[i] = e[i]
            store_upper(S, S0, i)
            pw0[i] = pw[i]
            for a in range(st0.shape[1]):  # (the kept columns: those a model changes)
                st0[i, a] = st[i, a]
            for a in range(hg.shape[1]):
                hg0[i, a] = hg[i, a]

    @cuda.jit
    def combine_kernel(n, keep, weight, x, v, rho, e, S, pw, st, hg, x0, v0, rho0, e0, S0, pw0,
                       st0, hg0):
        """SSP-RK3's convex combination ``y = keep y + weight y0`` of every integrated field
        (:func:`impactsph.integrate.combine_particle`, the CPU's ``combine_kept`` a
        particle)."""
        i = cuda.grid(1)
        if i < n:
            combine_particle(i, keep, weight, x, v, rho, e, S, pw, st, hg, x0, v0, rho0, e0,
                             S0, pw0, st0, hg0)

    @cuda.jit
    def weigh_kernel(n, weight, first, rate, mean):
        """A step's mean of a per-particle vector over its rate evaluations: ``mean =
        weight rate`` at the ``first``, ``mean += weight rate`` after (SSP-RK3's mean
        acceleration, as :meth:`impactsph.integrate.SspRk3Integrator.step` sums it, and its
        mean contact force)."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                if first:
                    mean[i, a] = weight * rate[i, a]
                else:
                    mean[i, a] += weight * rate[i, a]

    @cuda.jit
    def stretch_rows_kernel(n, x, x0, body, h, sx, sx0, sb, sh):
        """The stretch's rows of the particles (:func:`impactsph.physics.stretch.
        mirrored_rows`): their positions now and at t = 0, bodies and smoothing lengths."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                sx[i, a] = x[i, a]
                sx0[i, a] = x0[i, a]
            sb[i] = body[i]
            sh[i] = h[i]

    @cuda.jit
    def stretch_mirror_kernel(start, stop, n_real, sx, sx0, sb, sh, src, wall, points,
                              normals, kinds):
        """The stretch's rows of the ghosts ``start .. stop - 1`` (a stage: their sources
        are particles or ghosts of earlier stages), mirrored from their sources'
        (:func:`impactsph.physics.stretch.mirror_row`)."""
        k = start + cuda.grid(1)
        if k < stop:
            mirror_row(k, n_real, sx, sx0, sb, sh, src, wall, points, normals, kinds)

    @cuda.jit
    def largest_kernel(n, a, out):
        """The largest of ``a[:n]`` into ``out[0]`` (set to -inf before): the block's, then
        one atomic max a block (a maximum, exact in any order)."""
        sh = cuda.shared.array((1, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        sh[0, t] = a[i] if i < n else -math.inf
        _block_reduce(sh, 1, 0, 1, t)
        if t == 0:
            cuda.atomic.max(out, 0, sh[0, 0])

    @cuda.jit
    def stretch_kernel(n_rows, n_real, order, offsets, indices, sx, sx0, sb, sh, h0,
                       max_stretch, h):
        """(ST-1) for the particle at sorted position ``p``: ``h = h0 clamp(lambda, 1,
        max_stretch)`` with ``lambda`` its neighbourhood's largest principal stretch over the
        old list (:func:`impactsph.physics.stretch.stretch_row`; ``h0`` where its moment is
        singular), as :func:`impactsph.physics.stretch.stretched_smoothing_length`."""
        p = cuda.grid(1)
        if p < n_rows:
            i = order[p]
            if i < n_real:
                A = cuda.local.array((DIM, DIM), float64)
                B = cuda.local.array((DIM, DIM), float64)
                inv = cuda.local.array((3, 3), float64)
                F = cuda.local.array((3, 3), float64)
                C = cuda.local.array((3, 3), float64)
                lam = stretch_row(p, order, offsets, indices, sx, sx0, sb, sh, A, B, inv, F,
                                  C, DIM)
                factor = min(max(lam, 1.0), max_stretch) if lam > 0.0 else 1.0
                h[i] = h0[i] * factor

    @cuda.jit
    def mean_velocity_kernel(n, v0, v, work):
        """The compatible energy update's work velocity: each particle's mean velocity over
        the step, ``(v(t) + v(t + dt)) / 2`` (:meth:`impactsph.integrate.MidpointIntegrator.
        _compatible_energy`)."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                work[i, a] = (v0[i, a] + v[i, a]) * 0.5

    @cuda.jit
    def work_columns_kernel(n_rows, order, work, P, w_column):
        """The records' work velocity columns from ``work`` (a row per particle and ghost),
        in the list's order (:meth:`impactsph.physics.rates.CpuRates.work_energy`)."""
        p = cuda.grid(1)
        if p < n_rows:
            i = order[p]
            for a in range(DIM):
                P[p, w_column + a] = work[i, a]

    @cuda.jit
    def work_energy_kernel(n, dt, de_work, de_pairs, e):
        """The compatible energy update: ``e += dt (de_work - de_pairs)``, the pair forces'
        energy terms at the step's mean velocity in place of the evaluation's
        (:meth:`impactsph.solver.Solver.work_rates`)."""
        i = cuda.grid(1)
        if i < n:
            e[i] += dt * (de_work[i] - de_pairs[i])

    @cuda.jit
    def survey_kernel(n, x, v, rho, e, S, st, m, inertia, h, material, table, hourglass,
                      points, normals, part, bad):
        """Per block: min h/(c + |v|), KE, IE, momentum; the first bad value (atomic min of
        its code, which is exact), a particle behind a wall the last kind: each particle's
        part is the CPU's (:func:`impactsph.physics.survey.survey_particle`; the resident
        ``inertia``: the masses with the added masses, the inertia of the kinetic energy and
        the momentum; ``hourglass``: the hourglass control's zeta, 0 for none)."""
        sh = cuda.shared.array((6, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        for k in range(6):
            sh[k, t] = 0.0
        sh[0, t] = math.inf
        if i < n:
            first, step, ke, ie, p0, p1, p2 = survey_particle(
                i, n, x, v, rho[i] / st[i, THICKNESS_RATIO], rho, e, S, m, inertia[i], h,
                material, table, hourglass, points, normals, SURVEY_START, False)
            if first >= 0:
                cuda.atomic.min(bad, 0, first)
            sh[0, t] = step
            sh[1, t] = ke
            sh[2, t] = ie
            sh[3, t] = p0
            sh[4, t] = p1
            sh[5, t] = p2
        _block_reduce(sh, 6, 1, 0, t)
        if t == 0:
            for k in range(6):
                part[cuda.blockIdx.x, k] = sh[k, 0]

    @cuda.jit(device=True, inline=True)
    def _block_reduce(sh, width, n_min, n_max, t):
        """The block's rows of ``sh`` into row 0, column by column (the first ``n_min`` by
        their minimum, the last ``n_max`` by their maximum, the others summed), by a tree
        whose order is fixed: the same bits whatever the scheduling."""
        cuda.syncthreads()
        s = TPB // 2
        while s > 0:
            if t < s:
                for k in range(width):
                    if k < n_min:
                        sh[k, t] = min(sh[k, t], sh[k, t + s])
                    elif k >= width - n_max:
                        sh[k, t] = max(sh[k, t], sh[k, t + s])
                    else:
                        sh[k, t] += sh[k, t + s]
            cuda.syncthreads()
            s //= 2

    @cuda.jit(device=True, inline=True)
    def _gather_blocks(part, n_blocks, sh, width, n_min, n_max, t):
        """The blocks' partial results (rows of ``part``) into ``sh[:, 0]`` by one block:
        thread ``t`` folds blocks ``t, t + TPB, ...`` in order, then the tree."""
        for k in range(width):
            acc = math.inf if k < n_min else (-math.inf if k >= width - n_max else 0.0)
            for blk in range(t, n_blocks, TPB):
                if k < n_min:
                    acc = min(acc, part[blk, k])
                elif k >= width - n_max:
                    acc = max(acc, part[blk, k])
                else:
                    acc += part[blk, k]
            sh[k, t] = acc
        _block_reduce(sh, width, n_min, n_max, t)

    @cuda.jit
    def survey_finish(n_blocks, part, courant, bad, out):
        """One block: the blocks' partials (:func:`_gather_blocks`) into the survey's record."""
        sh = cuda.shared.array((6, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, 6, 1, 0, t)
        if t == 0:
            out[0] = courant * sh[0, 0]
            for k in range(1, 6):
                out[k] = sh[k, 0]
            out[6] = -1.0 if bad[0] == NO_BAD else float64(bad[0])
            bad[0] = NO_BAD

    @cuda.jit
    def layer_kernel(n, x, v, m, material, table, points, normals, layer, per_radian, dv, de,
                     force):
        """The walls' penalty layer on each particle (:func:`impactsph.boundaries.
        layer_push_particle`): added to its rates, its force into ``force`` for the books."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                force[i, a] = 0.0
            layer_push_particle(i, x, v, m, material, table, points, normals, layer, dv, de,
                                per_radian, force[i])

    @cuda.jit
    def wall_friction_kernel(n, x, v, m, material, table, contact_force, points, normals, mu,
                             reach, dv, de, force):
        """The walls' Coulomb friction on each particle, wall by wall
        (:func:`impactsph.boundaries.friction_particle`, as the CPU's
        :func:`~impactsph.boundaries.friction_push`): added to its rates, its force into
        ``force`` for the books."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                force[i, a] = 0.0
            for w in range(points.shape[0]):
                if mu[w] > 0.0:
                    friction_particle(i, w, x, v, m, material, table, contact_force, points,
                                      normals, mu, reach, dv, de, force[i])

    @cuda.jit
    def totals_kernel(n, m, de_visc, correction_books, pair_count, contact_force,
                      layer_force, friction_force, corrected, walls, part):
        """Per block: sum m de_visc, the correction's power and heating (sum m
        correction_books[:, 0], sum m correction_books[:, 1]), the pairs and (walls) the
        walls' push: the contact forces' sum and the penalty layer's."""
        sh = cuda.shared.array((TOTALS, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        for k in range(TOTALS):
            sh[k, t] = 0.0
        if i < n:
            sh[0, t] = m[i] * de_visc[i]
            sh[3, t] = pair_count[i]
            if corrected:
                sh[1, t] = m[i] * correction_books[i, 0]
                sh[2, t] = m[i] * correction_books[i, 1]
            if walls:  # the contact forces' sum is the walls' push (bodies' cancel)
                for a in range(DIM):
                    sh[4 + a, t] = contact_force[i, a]
            if friction_force.shape[0] > 0:
                for a in range(DIM):
                    sh[4 + a, t] += friction_force[i, a]
            if layer_force.shape[0] > 0:
                for a in range(DIM):
                    sh[4 + a, t] += layer_force[i, a]
        _block_reduce(sh, TOTALS, 0, 0, t)
        if t == 0:
            for k in range(TOTALS):
                part[cuda.blockIdx.x, k] = sh[k, 0]

    @cuda.jit
    def totals_finish(n_blocks, part, dt, weight, first, heating, books):
        """One block: the blocks' totals (:func:`_gather_blocks`) into the books: the powers
        and the walls' push times ``dt weight`` (nothing at weight 0, as the CPU's books;
        the viscous heating only if ``heating``: the compatible energy update books its work
        pass's instead of its corrector's), the pairs, and the step's mean push so far (set
        back at its ``first`` evaluation)."""
        sh = cuda.shared.array((TOTALS, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, TOTALS, 0, 0, t)
        if t == 0:
            if first:
                for a in range(3):
                    books[LAST_PUSH + a] = 0.0
            books[3] += sh[3, 0]
            if weight != 0.0:
                for k in range(TOTALS):
                    if k != 3 and (k != 0 or heating):
                        books[k] += dt * weight * sh[k, 0]
                    if k >= 4:
                        books[LAST_PUSH + k - 4] += weight * sh[k, 0]

    @cuda.jit
    def enforce_kernel(n, x, v, m, points, normals, scratch):
        """The walls' constraint on each particle (:func:`impactsph.boundaries.
        enforce_particle`); its count and impulse into ``scratch`` for the books."""
        i = cuda.grid(1)
        if i < n:
            for k in range(4):
                scratch[i, k] = 0.0
            scratch[i, 0] = enforce_particle(i, x, v, m, points, normals, scratch[i, 1:])

    @cuda.jit
    def enforce_sums(n, scratch, part):
        sh = cuda.shared.array((4, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        for k in range(4):
            sh[k, t] = scratch[i, k] if i < n else 0.0
        _block_reduce(sh, 4, 0, 0, t)
        if t == 0:
            for k in range(4):
                part[cuda.blockIdx.x, k] = sh[k, 0]

    @cuda.jit
    def enforce_finish(n_blocks, part, count_events, share, books):
        """One block: the constraint's events (if ``count_events``) and ``share`` times its
        impulse into the books (nothing at share 0, as the CPU's books)."""
        sh = cuda.shared.array((4, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, 4, 0, 0, t)
        if t == 0:
            if count_events:
                books[EVENTS] += sh[0, 0]
            if share != 0.0:
                for k in range(1, 4):
                    books[EVENTS + k] += share * sh[k, 0]

    @cuda.jit
    def clamp_sums(n_rows, rows, m, dv, part):
        """Per block, over the clamped particles ``rows``: the sum of ``m dv``, the rate of
        the momentum that the supports take from them."""
        sh = cuda.shared.array((3, TPB), float64)
        k = cuda.grid(1)
        t = cuda.threadIdx.x
        for a in range(3):
            sh[a, t] = 0.0
        if k < n_rows:
            i = rows[k]
            for a in range(DIM):
                sh[a, t] = m[i] * dv[i, a]
        _block_reduce(sh, 3, 0, 0, t)
        if t == 0:
            for a in range(3):
                part[cuda.blockIdx.x, a] = sh[a, 0]

    @cuda.jit
    def clamp_finish(n_blocks, part, dt, books):
        """One block: the supports' impulse over the step, minus ``dt`` times the blocks'
        sums (:meth:`impactsph.integrate.MidpointIntegrator._clamp_impulse`), into the
        books."""
        sh = cuda.shared.array((3, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, 3, 0, 0, t)
        if t == 0:
            for a in range(DIM):
                books[CLAMP + a] -= dt * sh[a, 0]

    @cuda.jit
    def body_kernel(n, b, body, m, inertia, v, e, pw, x, x0, force, part):
        """Per block, over body ``b``'s particles (:func:`impactsph.simulation.body_totals`):
        kinetic and internal energy, plastic work, the contact force (``force``, where it has
        rows), then the largest squared displacement."""
        sh = cuda.shared.array((BODY_WIDTH, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        for k in range(BODY_WIDTH):
            sh[k, t] = 0.0
        if i < n and body[i] == b:
            v2 = 0.0
            u2 = 0.0
            for a in range(DIM):
                v2 += v[i, a] * v[i, a]
                d = x[i, a] - x0[i, a]
                u2 += d * d
            sh[0, t] = 0.5 * inertia[i] * v2  # (the mass and the added mass)
            sh[1, t] = m[i] * e[i]
            sh[2, t] = m[i] * pw[i]
            if force.shape[0] > 0:
                for a in range(DIM):
                    sh[3 + a, t] = force[i, a]
            sh[BODY_WIDTH - 1, t] = u2
        _block_reduce(sh, BODY_WIDTH, 0, 1, t)
        if t == 0:
            for k in range(BODY_WIDTH):
                part[cuda.blockIdx.x, k] = sh[k, 0]

    @cuda.jit
    def body_finish(n_blocks, part, b, out):
        sh = cuda.shared.array((BODY_WIDTH, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, BODY_WIDTH, 0, 1, t)
        if t == 0:
            for k in range(BODY_WIDTH):
                out[b, k] = sh[k, 0]

    @cuda.jit
    def ghost_count_kernel(n, x, points, normals, kinds, reach, counts):
        """How many rigid walls' ghosts particle ``i`` has (``0 <= d < reach``, as
        :meth:`impactsph.boundaries.Walls.select`; the symmetry planes' come after)."""
        i = cuda.grid(1)
        if i < n:
            c = 0
            for w in range(points.shape[0]):
                d = 0.0
                for a in range(DIM):
                    d += (x[i, a] - points[w, a]) * normals[w, a]
                if d >= 0.0 and d < reach and kinds[w] != SYMMETRY:
                    c += 1
            counts[i] = c

    @cuda.jit
    def ghost_list_kernel(n, x, points, normals, kinds, reach, counts, ends, src, wall):
        """The rigid walls' ghosts' sources and walls, particle by particle, wall by wall:
        the order of :meth:`~impactsph.boundaries.Walls.select`."""
        i = cuda.grid(1)
        if i < n:
            k = ends[i] - counts[i]
            for w in range(points.shape[0]):
                d = 0.0
                for a in range(DIM):
                    d += (x[i, a] - points[w, a]) * normals[w, a]
                if d >= 0.0 and d < reach and kinds[w] != SYMMETRY:
                    src[k] = i
                    wall[k] = w
                    k += 1

    @cuda.jit
    def plane_count_kernel(n_rows, x, points, normals, w, reach, counts):
        """Whether row ``r`` (a particle, or a ghost selected before) is within ``reach``
        of the symmetry plane ``w`` (``0 <= d < reach``): its image is a ghost."""
        r = cuda.grid(1)
        if r < n_rows:
            d = 0.0
            for a in range(DIM):
                d += (x[r, a] - points[w, a]) * normals[w, a]
            counts[r] = 1 if d >= 0.0 and d < reach else 0

    @cuda.jit
    def plane_list_kernel(n_rows, x, points, normals, w, reach, ends, start, src, wall):
        """The symmetry plane ``w``'s ghosts, row by row, from ghost ``start`` on (``ends``:
        the inclusive prefix sum of :func:`plane_count_kernel`'s counts)."""
        r = cuda.grid(1)
        if r < n_rows:
            d = 0.0
            for a in range(DIM):
                d += (x[r, a] - points[w, a]) * normals[w, a]
            if d >= 0.0 and d < reach:
                k = start + ends[r] - 1
                src[k] = r
                wall[k] = w

    @cuda.jit
    def ghost_position_kernel(start, stop, src, wall, points, normals, n_real, x):
        """The positions of ghosts ``start`` to ``stop``: their sources' mirrored (as
        :func:`impactsph.boundaries.fill_ghost` places them), for the next plane's search."""
        k = start + cuda.grid(1)
        if k < stop:
            i = src[k]
            w = wall[k]
            d = 0.0
            for a in range(DIM):
                d += (x[i, a] - points[w, a]) * normals[w, a]
            for a in range(DIM):
                x[n_real + k, a] = x[i, a] - 2.0 * d * normals[w, a]

    @cuda.jit
    def inverse_kernel(n, order, position):
        """Each row's place in the packed records (the inverse of the list's order)."""
        p = cuda.grid(1)
        if p < n:
            position[order[p]] = p

    @cuda.jit
    def mirror_results_kernel(start, stop, src, wall, normals, kinds, n_real, position, P,
                              u_column, gradients):
        """After the pair kernel, for ghosts ``start`` to ``stop`` (one stage of the
        selection: a corner image's source ghost is of an earlier stage, mirrored before):
        :func:`impactsph.boundaries.mirror_ghost_results`, a ghost a thread."""
        k = start + cuda.grid(1)
        if k < stop:
            mirror_ghost_result(k, src, wall, normals, kinds, n_real, position, P, u_column,
                                DIM, gradients)

    @cuda.jit
    def mirror_matrices_kernel(start, stop, src, wall, normals, kinds, n_real, position, P,
                               c0):
        """After the correction matrices (or a reconstructing viscosity's gradients), for
        ghosts ``start`` to ``stop``: :func:`impactsph.boundaries.mirror_ghost_matrices`."""
        k = start + cuda.grid(1)
        if k < stop:
            source = cuda.local.array((DIM, DIM), float64)
            mirrored = cuda.local.array((DIM, DIM), float64)
            mirror_ghost_matrix(k, src, wall, normals, kinds, n_real, position, P, c0, DIM,
                                source, mirrored)

    @cuda.jit
    def ghost_fill_kernel(start, stop, src, wall, points, normals, kinds, n_real, x, v, rho, e,
                          S, carried, m, h, material, body, ghost_body0):
        """Ghosts ``start`` to ``stop`` (one stage of the selection: their sources are
        filled already) from their sources (:func:`impactsph.boundaries.fill_ghost`)."""
        k = start + cuda.grid(1)
        if k < stop:
            fill_ghost(k, src, wall, points, normals, kinds, n_real, x, v, rho, e, S, carried,
                       m, h, material, body, ghost_body0)

    @cuda.jit
    def displacement_kernel(n, x, reference, origin, largest, slot):
        """The largest squared displacement since the build into ``largest[slot]`` (zero
        before): the block's, then one atomic max per block (exact); the other slot is
        zeroed for the next test (no copy from the host a test)."""
        sh = cuda.shared.array((1, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        if i == 0:
            largest[1 - slot] = 0.0
        sh[0, t] = 0.0
        if i < n:
            s = 0.0
            for a in range(DIM):
                d = (x[i, a] - origin[a]) - float64(reference[i, a])
                s += d * d
            sh[0, t] = s
        _block_reduce(sh, 1, 0, 1, t)
        if t == 0:
            cuda.atomic.max(largest, slot, sh[0, 0])

    @cuda.jit
    def bounds_kernel(n, x, lo, hi):
        """The bounding box: the block's, then one atomic min and max per block and axis."""
        sh = cuda.shared.array((6, TPB), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        for a in range(3):
            sh[a, t] = math.inf
            sh[3 + a, t] = -math.inf
        if i < n:
            for a in range(DIM):
                sh[a, t] = x[i, a]
                sh[3 + a, t] = x[i, a]
        _block_reduce(sh, 6, 3, 3, t)
        if t == 0:
            for a in range(DIM):
                cuda.atomic.min(lo, a, sh[a, 0])
                cuda.atomic.max(hi, a, sh[3 + a, 0])

    @cuda.jit
    def cell_kernel(n, x, lo, radius, ncell, key, counts, reference):
        """Each particle's row-major cell (as the CPU builder clamps it), counted per cell;
        the reference positions for the staleness test."""
        i = cuda.grid(1)
        if i < n:
            k = 0
            for a in range(DIM):
                c = int((x[i, a] - lo[a]) / radius)
                if c < 0:
                    c = 0
                if c >= ncell[a]:
                    c = ncell[a] - 1
                k = k * ncell[a] + c
                reference[i, a] = x[i, a] - lo[a]
            key[i] = k
            cuda.atomic.add(counts, k, 1)

    @cuda.jit
    def scatter_kernel(n, key, counts, ends, fill, order):
        i = cuda.grid(1)
        if i < n:
            k = key[i]
            slot = ends[k] - counts[k] + cuda.atomic.add(fill, k, 1)
            order[slot] = i

    @cuda.jit
    def cell_sort_kernel(n_cells, counts, ends, order):
        """Each cell's particles in ascending number (insertion sort of a few entries)."""
        k = cuda.grid(1)
        if k < n_cells:
            start = ends[k] - counts[k]
            for p in range(start + 1, ends[k]):
                value = order[p]
                q = p - 1
                while q >= start and order[q] > value:
                    order[q + 1] = order[q]
                    q -= 1
                order[q + 1] = value

    @cuda.jit
    def gather_kernel(n, order, x, xs):
        p = cuda.grid(1)
        if p < n:
            for a in range(DIM):
                xs[p, a] = x[order[p], a]

    @cuda.jit
    def neighbour_kernel(n, xs, lo, radius, front, ncell, counts, ends, offsets, indices,
                         store, order, h, per_pair, support_per_h, skin):
        """The CPU builder's sweep for sorted position ``p``: its neighbours within
        ``radius`` in the 3^dim cells around its own, counted (``store`` False: into
        ``offsets[p + 1]``) or stored from ``offsets[p]``; in 2D and 3D those at or beyond
        ``front`` (the support) from the row's end back, as the CPU builder splits its rows
        (the device's kernels read whole rows: the order only keeps the two lists the same).
        ``per_pair`` (smoothing lengths that differ: ``h`` of each row, ``order`` the sorted
        positions' rows): each pair within its own ``support_per_h h_ij + skin`` and split
        at its own support, as the CPU's list with a radius per pair
        (:func:`impactsph.neighbours.kept_within2`)."""
        p = cuda.grid(1)
        if p >= n:
            return
        own = cuda.local.array(3, np.int64)
        for a in range(DIM):
            own[a] = min(max(int((xs[p, a] - lo[a]) / radius), 0), ncell[a] - 1)
        r2max = radius * radius
        r2front = front * front
        found = 0
        found_back = 0
        pos = offsets[p] if store else 0
        back = offsets[p + 1] - 1 if store else 0
        for s in range(STENCIL):
            t = s
            kc = 0
            inside = True
            for a in range(DIM):
                c = own[a] + t % 3 - 1
                t //= 3
                if c < 0 or c >= ncell[a]:
                    inside = False
                kc = kc * ncell[a] + c
            if not inside:
                continue
            for q in range(ends[kc] - counts[kc], ends[kc]):
                if q == p:
                    continue
                r2 = 0.0
                for a in range(DIM):
                    d = xs[p, a] - xs[q, a]
                    r2 += d * d
                limit = r2max
                front_limit = r2front
                if per_pair:  # (no inner list on the device: the CPU's r2inner is 0)
                    reach = 0.5 * support_per_h * (h[order[p]] + h[order[q]]) + skin
                    limit = min(r2max, reach * reach)
                    support_pq = reach - skin
                    front_limit = min(limit, support_pq * support_pq)
                if r2 < limit:
                    if store and DIM > 1 and r2 >= front_limit:
                        indices[back - found_back] = q
                        found_back += 1
                        continue
                    if store:
                        indices[pos + found] = q
                    found += 1
        if not store:
            offsets[p + 1] = found

    @cuda.jit
    def zero_kernel(a):
        i = cuda.grid(1)
        if i < a.shape[0]:
            a[i] = 0

    @cuda.jit
    def scan_chunks(a, n, chunk, sums):
        """Inclusive prefix sum within each chunk of ``chunk`` entries; the chunk's total."""
        c = cuda.grid(1)
        start = c * chunk
        if start < n:
            s = 0
            for k in range(start, min(start + chunk, n)):
                s += a[k]
                a[k] = s
            sums[c] = s

    @cuda.jit
    def scan_add(a, n, chunk, sums):
        """Add the (scanned) totals of the chunks before each chunk."""
        c = cuda.grid(1)
        if c >= 1 and c * chunk < n:
            add = sums[c - 1]
            for k in range(c * chunk, min((c + 1) * chunk, n)):
                a[k] += add

    @cuda.jit
    def drive_kernel(n_rows, rows, vx, vy, vz, v):
        """A driven region's particles ``rows`` at the prescribed velocity ``(vx, vy, vz)``
        (:meth:`impactsph.driven.Drivers.apply`)."""
        k = cuda.grid(1)
        if k < n_rows:
            i = rows[k]
            v[i, 0] = vx
            if DIM > 1:
                v[i, 1] = vy
            if DIM > 2:
                v[i, 2] = vz

    @cuda.jit
    def drive_finish(n_blocks, part, region, rate_x, rate_y, rate_z, vel_x, vel_y, vel_z, dt,
                     reactions, work):
        """One block: driven region ``region``'s reaction over the step, its prescribed
        momentum change over ``dt`` (``rate_*``) less the blocks' sums of ``m dv``
        (``clamp_sums`` over its rows), and its work at the velocity ``vel_*`` added to
        ``work[0]`` (:meth:`impactsph.driven.Drivers.account`)."""
        sh = cuda.shared.array((3, TPB), float64)
        t = cuda.threadIdx.x
        _gather_blocks(part, n_blocks, sh, 3, 0, 0, t)
        if t == 0:
            change = (rate_x, rate_y, rate_z)
            velocity = (vel_x, vel_y, vel_z)
            power = 0.0
            for a in range(DIM):
                force = change[a] - sh[a, 0]
                reactions[region, a] = force
                power += force * velocity[a]
            work[0] += power * dt

    @cuda.jit
    def scale_kernel(n, fraction, dv):
        """Added mass: each particle's force per own mass into its acceleration, ``dv *= m /
        (m + added)`` (:meth:`impactsph.solver.Solver.rates`)."""
        i = cuda.grid(1)
        if i < n:
            for a in range(DIM):
                dv[i, a] *= fraction[i]

    @cuda.jit
    def carry_kernel(n, st, factor, memory, carried):
        """A scheme with a viscosity switch: each particle's row of the passes' ``carried``
        (the common material state, then the factor and its memory: as
        :meth:`impactsph.solver.Solver._fill` makes it on the host)."""
        i = cuda.grid(1)
        if i < n:
            for c in range(CARRIED):
                carried[i, c] = st[i, c]
            carried[i, VISCOSITY_FACTOR] = factor[i]
            carried[i, VISCOSITY_MEMORY] = memory[i]

    @cuda.jit
    def gauge_kernel(rows, x, v, rho, e, S, pw, st, out):
        """The integrated fields of the particles ``rows`` (the gauges'), one row of ``out``
        each: position, velocity, density, specific energy, plastic work, the deviator's nine
        components, the material state."""
        k = cuda.grid(1)
        if k < rows.shape[0]:
            i = rows[k]
            for a in range(DIM):
                out[k, a] = x[i, a]
                out[k, DIM + a] = v[i, a]
            c = 2 * DIM
            out[k, c] = rho[i]
            out[k, c + 1] = e[i]
            out[k, c + 2] = pw[i]
            for a in range(3):
                for b in range(3):
                    out[k, c + 3 + 3 * a + b] = S[i, a, b]
            for j in range(st.shape[1]):
                out[k, c + 12 + j] = st[i, j]

    @cuda.jit
    def take_rows(rows, v, out):
        k = cuda.grid(1)
        if k < rows.shape[0]:
            for a in range(DIM):
                out[k, a] = v[rows[k], a]

    return dict(advance=advance_kernel, start=start_kernel, combine=combine_kernel,
                weigh=weigh_kernel, mean_velocity=mean_velocity_kernel,
                stretch_rows=stretch_rows_kernel, stretch_mirror=stretch_mirror_kernel,
                stretch=stretch_kernel, largest=largest_kernel,
                work_columns=work_columns_kernel, work_energy=work_energy_kernel,
                survey=survey_kernel,
                survey_finish=survey_finish,
                totals=totals_kernel, totals_finish=totals_finish, layer=layer_kernel,
                wall_friction=wall_friction_kernel,
                enforce=enforce_kernel,
                enforce_sums=enforce_sums, enforce_finish=enforce_finish, body=body_kernel,
                body_finish=body_finish, clamp_sums=clamp_sums, clamp_finish=clamp_finish,
                ghost_count=ghost_count_kernel, ghost_list=ghost_list_kernel,
                plane_count=plane_count_kernel, plane_list=plane_list_kernel,
                ghost_position=ghost_position_kernel, inverse=inverse_kernel,
                mirror_results=mirror_results_kernel, mirror_matrices=mirror_matrices_kernel,
                ghost_fill=ghost_fill_kernel,
                displacement=displacement_kernel, bounds=bounds_kernel, cell=cell_kernel,
                scatter=scatter_kernel, cell_sort=cell_sort_kernel, gather=gather_kernel,
                neighbours=neighbour_kernel, zero=zero_kernel, scan_chunks=scan_chunks,
                scan_add=scan_add, take_rows=take_rows, gauges=gauge_kernel,
                carry=carry_kernel, scale=scale_kernel, drive=drive_kernel,
                drive_finish=drive_finish)


def prefix_sum(kernels: dict, a, n: int, tpb: int, stream, buffer, depth: int = 0) -> None:
    """Inclusive prefix sum, in place, of the first ``n`` entries of the device array ``a``:
    each chunk of :data:`SCAN_CHUNK` entries by one thread, the chunks' totals the same way
    (recursively), then each chunk's offset added.  ``buffer(depth, size)``: a device array
    for the chunks' totals at that depth of the recursion."""
    chunks = (n + SCAN_CHUNK - 1) // SCAN_CHUNK
    if chunks == 0:
        return
    blocks = max(1, (chunks + tpb - 1) // tpb)
    sums = buffer(depth, chunks)
    kernels["scan_chunks"][blocks, tpb, stream](a, n, SCAN_CHUNK, sums)
    if chunks > 1:
        prefix_sum(kernels, sums, chunks, tpb, stream, buffer, depth + 1)
        kernels["scan_add"][blocks, tpb, stream](a, n, SCAN_CHUNK, sums)


class ResidentStep:
    """A run's state on the GPU, advanced on the device by Table 1's midpoint step or by
    SSP-RK3 (``integrator``, the case's ``time.integrator``).

    ``solver``: the run's :class:`~impactsph.solver.Solver`, whose backend is a
    :class:`~impactsph.gpu.GpuRates` (its rate kernels, stream and block size are used) and
    whose host neighbour list and ghosts are taken over at the start and kept in step at
    each :meth:`download` after a rebuild (a checkpoint stores them).  The host ``state`` is
    the copy the caller reads: :meth:`download` refreshes it, :meth:`upload` hands a changed
    one back.  Rigid walls (no symmetry planes): their ghosts are chosen, filled and the
    walls' constraint applied on the device.
    """

    def __init__(self, solver: Any, state: ParticleState, table: np.ndarray,
                 drivers: Any = None, integrator: str = "midpoint"):
        from .models import registry

        if integrator not in DEVICE_INTEGRATORS:
            raise ValueError(f"integrator = {integrator!r}: the device steps "
                             f"{', '.join(DEVICE_INTEGRATORS)}")
        #: ``time.integrator``: the midpoint step or SSP-RK3 (:meth:`step`)
        self.integrator = integrator

        backend = solver.backend
        self.solver = solver
        self.dim = state.dim
        self.n = state.n
        self.tpb = backend.threads_per_block
        if self.tpb & (self.tpb - 1) or not 1 <= self.tpb <= 512:
            raise ValueError(f"threads_per_block = {self.tpb}: the step's block sums need a "
                             f"power of two from 1 to 512")
        self.stream = backend._stream
        self.options = backend.options
        simulated = simulator_enabled()
        version = registry.version()
        self.rate_kernels = gpu_kernels(self.dim, simulated, version, self.options,
                                        backend.max_registers)
        self.k = step_kernels(self.dim, simulated, version, self.options, self.tpb)
        self.record_width = record_columns(self.rate_kernels[-1], self.dim, solver.viscosity)
        self.viscosity = solver.viscosity
        self.corrected = self.viscosity.correction is not None
        self.n_bodies = solver.n_bodies
        walls = solver.walls
        self.contact = self.n_bodies > 1 or walls is not None
        #: the hourglass control's zeta (0: none; its pass after the correction's, as on the
        #: CPU) and the Coulomb friction between bodies (0: none; its pass after the pairs')
        self.hourglass = float(solver.hourglass)
        self.friction = float(self.options.contact_friction) if self.n_bodies > 1 else 0.0
        #: a scheme with a viscosity switch: its factors and memories (a state of the rates,
        #: not integrated) on the device, set by each evaluation's switch kernel for the next
        self.switched = self.viscosity.switch is not None
        #: the compatible energy update (``time.energy_update = "compatible"``: the passes
        #: compiled with the records' work velocity): a work pass after each step
        self.compatible = bool(self.options.compatible_energy)
        #: the driven regions (:class:`impactsph.driven.Drivers`, whose prescribed velocities
        #: the host evaluates), or None; their reactions and work are kept on the device
        self.drivers = drivers
        self.support = SUPPORT_RADIUS * float(state.smoothing_length.max())
        self.skin = solver.neighbours.skin
        self.radius = solver.neighbours.radius
        #: a smoothing length that follows the stretch (``kernel.max_stretch`` > 1): set at
        #: each rebuild from the old list, the support, skin and radius with it (as
        #: :meth:`impactsph.solver.Solver._build`), from the smoothing lengths at t = 0
        self.max_stretch = float(solver.max_stretch)
        self.skin_fraction = float(solver.skin_fraction)
        self.h_reference = (cuda.to_device(np.ascontiguousarray(solver._h_reference,
                                                                np.float64), stream=backend._stream)
                            if self.max_stretch > 1.0 else None)
        self.blocks = max(1, (self.n + self.tpb - 1) // self.tpb)
        s = self.stream
        dim = self.dim
        #: the symmetry planes (their wall numbers), whose ghosts are chosen after the rigid
        #: walls', plane by plane, and take their sources' per-particle results mirrored
        self.planes = (np.flatnonzero(walls.kinds == boundaries.SYMMETRY) if walls is not None
                       else np.zeros(0, np.int64))
        if walls is not None:
            self.points = cuda.to_device(np.ascontiguousarray(walls.points), stream=s)
            self.normals = cuda.to_device(np.ascontiguousarray(walls.normals), stream=s)
            self.kinds = cuda.to_device(np.ascontiguousarray(walls.kinds), stream=s)
            rigid = np.flatnonzero(walls.kinds != boundaries.SYMMETRY)  # (the penalty layer's)
            self.rigid_points = cuda.to_device(np.ascontiguousarray(walls.points[rigid]),
                                               stream=s)
            self.rigid_normals = cuda.to_device(np.ascontiguousarray(walls.normals[rigid]),
                                                stream=s)
        else:
            self.points = cuda.device_array((0, dim), np.float64, stream=s)
            self.normals = cuda.device_array((0, dim), np.float64, stream=s)
            self.kinds = None
            self.rigid_points, self.rigid_normals = self.points, self.normals
        self.walls = walls
        #: the passes' record columns (the viscous acceleration's, the matrices')
        self.columns = compiled_passes(dim, simulated, self.options)
        #: the ghosts' stages, ``(first, last)`` each: the rigid walls', then each symmetry
        #: plane's (a ghost's source is a particle or a ghost of an earlier stage)
        self.stages: list[tuple[int, int]] = []
        #: the walls' penalty layer (spacings), 0 for none, and whether its push is per radian
        #: (axisymmetry: the solver's)
        self.layer = solver.wall_layer if walls is not None else 0.0
        self.per_radian = bool(solver._axisymmetric)
        #: the walls' Coulomb friction (their coefficients, on the device), or None
        self.mu = (cuda.to_device(np.ascontiguousarray(walls.friction, np.float64), stream=s)
                   if walls is not None and (walls.friction > 0.0).any() else None)
        #: rate evaluations and rebuilds done on the device since :meth:`Simulation._fold`
        #: took them (the pair evaluations are in the books)
        self.rate_evaluations = 0
        self.builds = 0
        self.downloads = 0  #: the state's downloads (each the whole state)
        self._list_builds = 0  # device rebuilds not yet copied into the host list
        self._host_list = None  # the host NeighbourList the device list came from
        self.capacity = 0  # rows of the extended arrays (particles and ghosts)
        self._buffers: dict[str, Any] = {}  # the builds' arrays, kept and grown
        self._probes: dict[bytes, tuple] = {}  # each probe's rows and output on the device
        self.n_ghosts = 0
        self.n_cells = 0  #: the cells of the last device build's grid (0: none yet)
        #: whether the host state holds the latest values (after a download or an upload)
        self.host_current = True
        self._allocate(state, table)
        self.upload(state)

    # -- device memory -----------------------------------------------------------------------
    def layout(self) -> DeviceLayout:
        """What sets the sizes of this run's device arrays (:mod:`impactsph.gpu_memory`,
        whose :meth:`~impactsph.gpu_memory.DeviceLayout.of_case` gives the same for its
        case before the run)."""
        walls = self.walls
        return DeviceLayout(
            dim=self.dim, strength_width=int(self.now["material_state"].shape[1]),
            record_columns=int(self.record_width),
            record_bytes=int(np.dtype(self.options.record_dtype).itemsize),
            carried=PASS_CARRIED if self.switched else 0,
            walls=walls is not None, planes=bool(self.planes.shape[0]),
            n_walls=0 if walls is None else len(walls), layer=self.layer > 0.0,
            wall_friction=self.mu is not None, contact=self.contact, bodies=self.n_bodies,
            corrected=self.corrected, switched=self.switched, hourglass=self.hourglass > 0.0,
            ssp=self.integrator == "ssp_rk3",
            step_means=self.drivers is not None or self.clamped_rows.shape[0] > 0,
            compatible=self.compatible, stretch=self.max_stretch > 1.0,
            added_inertia=self.fraction is not None,
            state_kept=int(self.start["material_state"].shape[1]), threads_per_block=self.tpb)

    def allocated(self) -> dict[int, tuple[int, str]]:
        """Every device allocation this run holds (the rate backend's too), each once:
        ``{key: (bytes, path)}`` (:func:`impactsph.gpu_memory.arrays_of`)."""
        return arrays_of(SimpleNamespace(step=self, rates=self.solver.backend), "device",
                         depth=6, device=True)

    def _allocate(self, state: ParticleState, table: np.ndarray) -> None:
        n, dim, s = self.n, self.dim, self.stream
        empty = cuda.device_array
        self.now = {f: empty(getattr(state, f).shape, getattr(state, f).dtype, stream=s)
                    for f in INTEGRATED}
        # the deviator's start copy: its six components (the advance's S0); the material
        # state's first columns, those a model changes (the CPU's start copy's:
        # impactsph.integrate.state_kept_of_table)
        kept = integrate.state_kept_of_table(integrate.stage_options(
            table, self.options.plane_stress, self.options.axisymmetric), table)
        shapes = {f: getattr(state, f).shape for f in INTEGRATED}
        shapes["deviatoric_stress"] = (n, 6)
        shapes["material_state"] = (n, kept)

        def integrated_copy() -> dict:
            return {f: empty(shapes[f], getattr(state, f).dtype, stream=s) for f in INTEGRATED}

        self.start = integrated_copy()
        ssp = self.integrator == "ssp_rk3"
        #: SSP-RK3: the second and third stages' start (``y1``, then ``y2`` in its buffers),
        #: the step's mean acceleration (the supports' impulse, the driven regions' books)
        #: and, with several bodies, its mean contact force (their history columns)
        self.kept = integrated_copy() if ssp else None
        books = self.drivers is not None or bool(state.clamped.any())  # (the CPU's test)
        self.mean_dv = empty((n if ssp and books else 0, dim), np.float64, stream=s)
        self.mean_force = empty((n if ssp and self.n_bodies > 1 else 0, dim), np.float64,
                                stream=s)
        #: the compatible energy update: the corrector's pair energy rates, and the work
        #: pass's outputs (its specific-energy rates, heating and pairs are read)
        self.de_pairs = empty(n if self.compatible else 0, np.float64, stream=s)
        if self.compatible:
            self.work_out = {"drho": empty(n, np.float64, stream=s),
                             "dv": empty((n, dim), np.float64, stream=s),
                             "de": empty(n, np.float64, stream=s),
                             "de_visc": empty(n, np.float64, stream=s),
                             "contact_force": empty((0, dim), np.float64, stream=s),
                             "pair_count": empty(n, np.int32, stream=s),
                             "dS": empty((n, 6), np.float64, stream=s),
                             "gradients": empty((0, dim, dim), np.float64, stream=s)}
        self.const = {f: empty(getattr(state, f).shape, getattr(state, f).dtype, stream=s)
                      for f in CONSTANT}
        self.table = cuda.to_device(np.ascontiguousarray(table), stream=s)
        contact_rows = n if self.contact else 0
        corr_rows = n if self.corrected else 0  # AC's correction: only where it is used
        self.out = {"drho": empty(n, np.float64, stream=s), "dv": empty((n, dim), np.float64),
                    "de": empty(n, np.float64), "de_visc": empty(n, np.float64),
                    "contact_force": empty((contact_rows, dim), np.float64),
                    "pair_count": empty(n, np.int32), "dS": empty((n, 6), np.float64),
                    "correction_books": empty((corr_rows, 2), np.float64),
                    "dhg": empty((n, dim if self.hourglass > 0.0 else 0), np.float64),
                    "gradients": empty((0, dim, dim), np.float64)}
        self.survey_part = empty((self.blocks, 6), np.float64)
        self.survey_out = empty(SURVEY_WIDTH, np.float64)
        self.bad = cuda.to_device(np.array([NO_BAD], dtype=np.int64), stream=s)
        self.totals_part = empty((self.blocks, TOTALS), np.float64)
        self.books = cuda.to_device(np.zeros(BOOKS_WIDTH), stream=s)
        #: the staleness tests' largest squared displacement, in two slots taken in turn
        self.largest = cuda.to_device(np.zeros(2), stream=s)
        self._largest_slots = (self.largest[0:1], self.largest[1:2])
        self._slot = 0
        self.body_part = empty((self.blocks, 4 + dim), np.float64)
        self.body_out = empty((max(self.n_bodies, 1), 4 + dim), np.float64)
        self.origin = empty(dim, np.float64)
        if self.walls is not None:
            self.scratch = empty((n, 4), np.float64)
            self.enforce_part = empty((self.blocks, 4), np.float64)
        self.layer_force = empty((n if self.layer > 0.0 else 0, dim), np.float64)
        self.friction_force = empty((n if self.mu is not None else 0, dim), np.float64)
        switch_rows = n if self.switched else 0
        self.switch = {name: empty(switch_rows, np.float64, stream=s)
                       for name in ("factor", "memory", "next_factor", "next_memory")}
        regions = self.drivers.regions if self.drivers is not None else []
        self.driven = [(cuda.to_device(np.ascontiguousarray(r.rows, np.int64), stream=s),
                        empty((max(1, (r.rows.shape[0] + self.tpb - 1) // self.tpb), 3),
                              np.float64, stream=s)) for r in regions]
        self.reactions = cuda.to_device(np.zeros((max(len(regions), 1), 3)), stream=s)
        self.drive_work = cuda.to_device(np.zeros(1), stream=s)
        self._accounted = False  # whether a step has booked the regions' reactions

    def _rows(self, rows: int) -> None:
        """The arrays of every row (particles, then ghosts) for ``rows`` rows: the state's
        own without walls; with walls, extended arrays (reallocated with a margin when the
        ghosts outgrow them, their particles' constant rows copied in)."""
        s = self.stream
        if self.walls is None:
            if self.capacity == 0:
                self.ext = {"x": self.now["position"], "v": self.now["velocity"],
                            "rho": self.now["density"], "e": self.now["specific_energy"],
                            "S": self.now["deviatoric_stress"],
                            "carried": (cuda.device_array((rows, PASS_CARRIED), np.float64,
                                                          stream=s) if self.switched
                                        else self.now["material_state"]),
                            "m": self.const["mass"], "h": self.const["smoothing_length"],
                            "material": self.const["material"], "body": self.const["body"]}
                self._packed(rows)
            return
        if rows <= self.capacity:
            return
        capacity = rows + rows // 8 + 16
        width = PASS_CARRIED if self.switched else self.now["material_state"].shape[1]
        empty = cuda.device_array
        self.ext = {"x": empty((capacity, self.dim), np.float64, stream=s),
                    "v": empty((capacity, self.dim), np.float64, stream=s),
                    "rho": empty(capacity, np.float64, stream=s),
                    "e": empty(capacity, np.float64, stream=s),
                    "S": empty((capacity, 3, 3), np.float64, stream=s),
                    "carried": empty((capacity, width), np.float64, stream=s),
                    "m": empty(capacity, np.float64, stream=s),
                    "h": empty(capacity, np.float64, stream=s),
                    "material": empty(capacity, np.int32, stream=s),
                    "body": empty(capacity, np.int32, stream=s)}
        self._constant_rows()
        self._packed(capacity)

    def _constant_rows(self) -> None:
        """The particles' constant fields into their rows of the extended arrays."""
        n, s = self.n, self.stream
        for name, field in (("m", "mass"), ("h", "smoothing_length"), ("material", "material"),
                            ("body", "body")):
            self.ext[name][:n].copy_to_device(self.const[field], stream=s)

    def _packed(self, rows: int) -> None:
        """The packed records, the reference positions and, with the hourglass control,
        the rows' velocity gradients (the pair kernel's, which the hourglass kernel reads) for
        ``rows`` rows."""
        self.capacity = rows
        self.packed = cuda.device_array((rows, self.record_width), self.options.record_dtype,
                                        order=RECORD_ORDER, stream=self.stream)
        if self.hourglass > 0.0:
            self.out["gradients"] = cuda.device_array((rows, self.dim, self.dim), np.float64,
                                                      stream=self.stream)
        reference = cuda.device_array((rows, self.dim), np.float32, stream=self.stream)
        if getattr(self, "reference", None) is not None:  # the particles' rows kept
            reference[: self.n].copy_to_device(self.reference[: self.n], stream=self.stream)
        self.reference = reference

    def _fill(self) -> None:
        """The particles' rows of the extended arrays from the state, and the ghosts' from
        their sources (with walls)."""
        s, n, ext, now = self.stream, self.n, self.ext, self.now
        if self.switched:  # the common material state and the factors, in the passes' columns
            self._launch("carry", n, n, now["material_state"], self.switch["factor"],
                         self.switch["memory"], ext["carried"])
        if self.walls is None:
            return
        for name, field in (("x", "position"), ("v", "velocity"), ("rho", "density"),
                            ("e", "specific_energy"), ("S", "deviatoric_stress"),
                            ("carried", "material_state")):
            if name != "carried" or not self.switched:
                ext[name][:n].copy_to_device(now[field], stream=s)
        for first, last in self.stages:  # (in order: a corner image's source filled first)
            self._launch("ghost_fill", last - first, first, last, self.ghost_src,
                         self.ghost_wall, self.points, self.normals, self.kinds, n, ext["x"],
                         ext["v"], ext["rho"], ext["e"], ext["S"], ext["carried"], ext["m"],
                         ext["h"], ext["material"], ext["body"], self.n_bodies)

    def _stages_of(self, wall: np.ndarray) -> list[tuple[int, int]]:
        """The stages of the ghosts of walls ``wall`` (in the order of
        :meth:`impactsph.boundaries.Walls.select`): the rigid walls' ghosts, then each
        symmetry plane's."""
        if wall.shape[0] == 0:
            return []
        if self.planes.shape[0] == 0:
            return [(0, int(wall.shape[0]))]
        stage = np.zeros(wall.shape[0], np.int64)
        for s, w in enumerate(self.planes):
            stage[wall == w] = s + 1
        cuts = np.flatnonzero(np.diff(stage)) + 1
        edges = [0, *cuts.tolist(), int(wall.shape[0])]
        return list(zip(edges[:-1], edges[1:], strict=True))

    def _inverse(self) -> None:
        """Each row's place in the packed records (a symmetry plane's ghosts' mirror)."""
        rows = self.n + self.n_ghosts
        self.position = self._buffer("position", rows, np.int64)
        self._launch("inverse", rows, rows, self.order, self.position)

    def _buffer(self, name: str, rows: int, dtype, width: int | None = None):
        """The first ``rows`` rows of a device array kept between rebuilds (grown by
        1/:data:`BUFFER_MARGIN` when too small): numba frees device memory lazily, and a free
        waits for the device, so the builds reuse their arrays rather than allocating each
        time."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape[0] < rows:
            size = max(rows + rows // BUFFER_MARGIN, 1)
            buf = cuda.device_array(size if width is None else (size, width), dtype,
                                    stream=self.stream)
            self._buffers[name] = buf
        return buf[:rows]

    def _scratch(self, name: str, rows: int, dtype, width: int | None, room):
        """A build's scratch array of ``rows`` rows (of ``width`` columns): the rate output
        ``room`` itself, reinterpreted as ``dtype``, when its rows are enough (a build runs
        before the evaluation that overwrites the outputs, after the stage that read them),
        else a kept buffer (walls' ghosts add rows)."""
        if room.shape[0] >= rows and (room.shape[1:] == (() if width is None else (width,))):
            return room[:rows].view(dtype)
        return self._buffer(name, rows, dtype, width)

    def _fetch(self, device_array) -> np.ndarray:
        """A device array's values on the host, once they are there (the copy is queued
        on the stream; the stream is then waited for)."""
        host = device_array.copy_to_host(stream=self.stream)
        self.stream.synchronize()
        return host

    def _launch(self, kernel: str, threads: int, *args) -> None:
        blocks = max(1, (threads + self.tpb - 1) // self.tpb)
        self.k[kernel][blocks, self.tpb, self.stream](*args)

    def upload(self, state: ParticleState) -> None:
        """Hand the host ``state`` (and the host neighbour list and ghosts, if the solver
        holds another list than the device's) to the device."""
        s = self.stream
        for f in INTEGRATED:
            if getattr(state, f).size:
                self.now[f].copy_to_device(np.ascontiguousarray(getattr(state, f)), stream=s)
        for f in CONSTANT:
            self.const[f].copy_to_device(np.ascontiguousarray(getattr(state, f)), stream=s)
        if self.switched:
            for name in ("factor", "memory"):
                self.switch[name].copy_to_device(
                    np.ascontiguousarray(getattr(state, f"viscosity_{name}"), np.float64),
                    stream=s)
        self.factor_time = float(state.viscosity_factor_time)
        # smoothing lengths that differ: the list's radius per pair (Solver._build's test)
        h = state.smoothing_length
        self.per_pair = bool(self.max_stretch > 1.0 or (h.shape[0] > 0 and h.max() > h.min()))
        # the inertia of the books' impulses and the kinetic energy (mass and added mass: the
        # masses themselves where nothing is added, 8 B a particle less), and with added mass
        # the fraction that turns forces per own mass into accelerations
        self.inertia = (cuda.to_device(np.ascontiguousarray(state.mass + state.added_mass),
                                       stream=s) if state.added_mass.any()
                        else self.const["mass"])
        fraction = state.inertia_fraction()
        self.fraction = (None if fraction is None
                         else cuda.to_device(np.ascontiguousarray(fraction), stream=s))
        clamped = np.flatnonzero(state.clamped).astype(np.int64)
        self.clamped_rows = cuda.device_array(clamped.shape[0], np.int64, stream=s)
        if clamped.shape[0]:  # (no copy of nothing)
            self.clamped_rows.copy_to_device(clamped, stream=s)
        self.clamp_part = cuda.device_array(
            (max(1, (clamped.shape[0] + self.tpb - 1) // self.tpb), 3), np.float64, stream=s)
        if self.walls is not None and self.capacity:  # the kernels read the extended rows
            self._constant_rows()
        nl = self.solver.neighbours
        if nl is not self._host_list:
            src = np.ascontiguousarray(self.solver._ghost_src, np.int64)
            wall = np.ascontiguousarray(self.solver._ghost_wall, np.int64)
            self.n_ghosts = int(src.shape[0])
            self.ghost_src = cuda.device_array(self.n_ghosts, np.int64, stream=s)
            self.ghost_wall = cuda.device_array(self.n_ghosts, np.int64, stream=s)
            if self.n_ghosts:  # (no copy of nothing)
                self.ghost_src.copy_to_device(src, stream=s)
                self.ghost_wall.copy_to_device(wall, stream=s)
            self.stages = self._stages_of(wall)
            rows = self.n + self.n_ghosts
            self.capacity = 0  # new arrays: the constants' rows are copied in
            self._rows(rows)
            self.order = cuda.to_device(np.ascontiguousarray(nl.order), stream=s)
            self.offsets = cuda.to_device(np.ascontiguousarray(nl.offsets), stream=s)
            self.indices = cuda.to_device(np.ascontiguousarray(nl.indices), stream=s)
            self.reference[:rows].copy_to_device(np.ascontiguousarray(
                nl.reference_positions[:rows]), stream=s)
            self.origin.copy_to_device(np.ascontiguousarray(nl.reference_origin, np.float64),
                                       stream=s)
            if self.planes.shape[0]:
                self._inverse()
            self._host_list = nl
            self._list_builds = 0
        s.synchronize()
        self.host_current = True

    def download(self, state: ParticleState) -> None:
        """The device's state into the host ``state`` (nothing when it is current); after a
        rebuild also the neighbour list and the ghosts into the solver's."""
        if self.host_current:
            return
        self.downloads += 1
        s = self.stream
        for f in INTEGRATED:
            if getattr(state, f).size:
                self.now[f].copy_to_host(getattr(state, f), stream=s)
        if self.switched:
            self.switch["factor"].copy_to_host(state.viscosity_factor, stream=s)
            self.switch["memory"].copy_to_host(state.viscosity_memory, stream=s)
        state.viscosity_factor_time = self.factor_time
        if self.max_stretch > 1.0:  # (set at the device's rebuilds)
            self.const["smoothing_length"].copy_to_host(state.smoothing_length, stream=s)
        if self._list_builds:
            nl = self.solver.neighbours
            rows = self.n + self.n_ghosts
            nl.order = self._fetch(self.order).astype(np.int32)
            nl.offsets = self._fetch(self.offsets)
            nl.indices = self._fetch(self.indices)
            nl.reference_positions = self._fetch(self.reference[:rows])
            nl.reference_origin = self._fetch(self.origin)
            nl.radius, nl.skin = self.radius, self.skin  # (the stretch moves them)
            # the device builds no inner list (its correction kernel reads the whole list, to
            # the same sums): the host's, of an older build, goes
            nl.inner_reach, nl.inner_radius = 1.0, 0.0
            nl.inner_ends = None
            # nor the rows' splits (its rows are split as the CPU's, but it keeps no marks):
            # the host's, of an older build, go, and the CPU passes test whole rows
            nl.splits = None
            src, wall = ((self._fetch(self.ghost_src), self._fetch(self.ghost_wall))
                         if self.n_ghosts else (np.zeros(0, np.int64), np.zeros(0, np.int64)))
            s.synchronize()
            self.solver.restore(state, nl, src, wall)  # the host's ghosts and buffers too
            self._list_builds = 0
        s.synchronize()
        self.host_current = True

    def rows(self, rows: np.ndarray) -> np.ndarray:
        """The velocities of the particles ``rows`` (a probe), without the rest."""
        key = rows.tobytes()
        if key not in self._probes:  # a probe's rows, on the device once
            self._probes[key] = (
                cuda.to_device(np.ascontiguousarray(rows, np.int64), stream=self.stream),
                cuda.device_array((rows.shape[0], self.dim), np.float64, stream=self.stream))
        d_rows, out = self._probes[key]
        if rows.shape[0]:
            self._launch("take_rows", rows.shape[0], d_rows, self.now["velocity"], out)
        return self._fetch(out)

    def gauge_rows(self, rows: np.ndarray) -> SimpleNamespace:
        """The integrated fields of the particles ``rows`` (a run's gauges), as
        :meth:`impactsph.gauges.Gauges.rows_of` takes them from a host state, in one kernel
        and one copy."""
        key = b"gauges" + rows.tobytes()
        now, dim = self.now, self.dim
        width = 2 * dim + 12 + now["material_state"].shape[1]
        if key not in self._probes:  # (the gauges' rows, on the device once)
            self._probes[key] = (
                cuda.to_device(np.ascontiguousarray(rows, np.int64), stream=self.stream),
                cuda.device_array((rows.shape[0], width), np.float64, stream=self.stream))
        d_rows, out = self._probes[key]
        if rows.shape[0]:
            self._launch("gauges", rows.shape[0], d_rows, now["position"], now["velocity"],
                         now["density"], now["specific_energy"], now["deviatoric_stress"],
                         now["plastic_work"], now["material_state"], out)
        values = self._fetch(out)
        c = 2 * dim
        return SimpleNamespace(position=values[:, :dim], velocity=values[:, dim: c],
                               density=values[:, c], specific_energy=values[:, c + 1],
                               plastic_work=values[:, c + 2],
                               deviatoric_stress=values[:, c + 3: c + 12].reshape(-1, 3, 3),
                               material_state=values[:, c + 12:])

    def books_now(self) -> dict[str, Any]:
        """The run's books as the device holds them (the running totals are kept there, from
        the values :meth:`set_books` gave, so that they add up in the order the CPU adds
        them whenever they are read): ``heating``, ``correction_work``,
        ``correction_heating`` (J), ``pairs``, ``wall_impulse`` (N s), ``events``,
        ``constraint_impulse`` (N s), ``push`` (N, the last step's) and ``clamp_impulse``
        (N s, the supports' on the clamped particles)."""
        books = self._fetch(self.books)
        dim = self.dim
        return {"heating": books[0], "correction_work": books[1],
                "correction_heating": books[2], "pairs": int(books[3]),
                "wall_impulse": books[4: 4 + dim].copy(), "events": int(books[EVENTS]),
                "constraint_impulse": books[EVENTS + 1: EVENTS + 1 + dim].copy(),
                "push": books[LAST_PUSH: LAST_PUSH + dim].copy(),
                "clamp_impulse": books[CLAMP: CLAMP + dim].copy()}

    def set_books(self, books: dict[str, Any]) -> None:
        """The run's books (as :meth:`books_now` names them) onto the device."""
        dim = self.dim
        values = np.zeros(BOOKS_WIDTH)
        values[0] = books["heating"]
        values[1] = books["correction_work"]
        values[2] = books["correction_heating"]
        values[3] = books["pairs"]
        values[4: 4 + dim] = books["wall_impulse"]
        values[EVENTS] = books["events"]
        values[EVENTS + 1: EVENTS + 1 + dim] = books["constraint_impulse"]
        values[LAST_PUSH: LAST_PUSH + dim] = books["push"]
        values[CLAMP: CLAMP + dim] = books["clamp_impulse"]
        self.books.copy_to_device(values, stream=self.stream)
        self._set_drivers()

    def body_totals(self) -> np.ndarray:
        """Per body, from the device state, the columns of
        :func:`impactsph.simulation.body_totals` (kinetic and internal energy, plastic work,
        the largest squared displacement) and then the body's contact force (the last
        evaluation's: the midpoint step's mean; SSP-RK3's is its own)."""
        now, c, n, dim = self.now, self.const, self.n, self.dim
        force = self.out["dv"][:0]
        if self.n_bodies > 1:
            force = self.mean_force if self.integrator == "ssp_rk3" else self.out["contact_force"]
        for b in range(self.n_bodies):
            self._launch("body", n, n, b, c["body"], c["mass"], self.inertia, now["velocity"],
                         now["specific_energy"], now["plastic_work"], now["position"],
                         c["initial_position"], force, self.body_part)
            self._launch("body_finish", 1, self.blocks, self.body_part, b, self.body_out)
        out = self._fetch(self.body_out)
        return np.concatenate([out[:, :3], out[:, 3 + dim:], out[:, 3: 3 + dim]], axis=1)

    # -- the neighbour list --------------------------------------------------------------------
    def _stale(self) -> bool:
        if self.skin <= 0.0:
            return True
        slot = self._slot
        self._slot = 1 - slot
        self._launch("displacement", self.n, self.n, self.now["position"], self.reference,
                     self.origin, self.largest, slot)
        largest = self._fetch(self._largest_slots[slot])[0]
        return bool(math.sqrt(largest) > 0.5 * self.skin)

    def _scan(self, a, n: int, depth: int = 0) -> None:
        """Inclusive prefix sum of the first ``n`` entries of the device array ``a``
        (:func:`prefix_sum`)."""
        prefix_sum(self.k, a, n, self.tpb, self.stream,
                   lambda level, size: self._buffer(f"scan{level}", size, a.dtype), depth)

    def _grown(self, name: str, rows: int, keep: int, dtype, width: int | None = None):
        """:meth:`_buffer` with its first ``keep`` rows kept where it has to grow."""
        old = self._buffers.get(name)
        buf = self._buffer(name, rows, dtype, width)
        if old is not None and keep and self._buffers[name] is not old:
            buf[:keep].copy_to_device(old[:keep], stream=self.stream)
        return buf

    def _select_ghosts(self) -> None:
        """The walls' ghosts of the particles within reach of them, in the order of
        :meth:`impactsph.boundaries.Walls.select`: the rigid walls' (particle by particle,
        wall by wall), then for each symmetry plane in turn the images of every row so far
        (particles and the ghosts before) within reach of it, row by row: a stage each."""
        n, s = self.n, self.stream
        if self.walls is None:
            self._rows(n)
            return
        x = self.now["position"]
        reach = self.support + self.skin
        counts = self._buffer("ghost_counts", n, np.int64)
        self._launch("ghost_count", n, n, x, self.points, self.normals, self.kinds, reach,
                     counts)
        ends = self._buffer("ghost_ends", n, np.int64)
        ends.copy_to_device(counts, stream=s)
        self._scan(ends, n)
        total = int(self._fetch(ends[n - 1:])[0]) if n else 0
        src = self._grown("ghost_src", total, 0, np.int64)
        wall = self._grown("ghost_wall", total, 0, np.int64)
        self._launch("ghost_list", n, n, x, self.points, self.normals, self.kinds, reach,
                     counts, ends, src, wall)
        stages = [(0, total)] if total else []
        if self.planes.shape[0] and n:
            # every row's position so far, for the next plane's search (the ghosts' as the
            # fill will place them)
            xs = self._grown("ghost_x", n + total, 0, np.float64, self.dim)
            xs[:n].copy_to_device(x, stream=s)
            if total:
                self._launch("ghost_position", total, 0, total, src, wall, self.points,
                             self.normals, n, xs)
            for w in self.planes:
                rows = n + total
                near = self._buffer("plane_ends", rows, np.int64)
                self._launch("plane_count", rows, rows, xs, self.points, self.normals, int(w),
                             reach, near)
                self._scan(near, rows)
                added = int(self._fetch(near[rows - 1:])[0])
                if not added:
                    continue
                src = self._grown("ghost_src", total + added, total, np.int64)
                wall = self._grown("ghost_wall", total + added, total, np.int64)
                self._launch("plane_list", rows, rows, xs, self.points, self.normals, int(w),
                             reach, near, total, src, wall)
                xs = self._grown("ghost_x", rows + added, rows, np.float64, self.dim)
                self._launch("ghost_position", added, total, total + added, src, wall,
                             self.points, self.normals, n, xs)
                stages.append((total, total + added))
                total += added
        self.n_ghosts = total
        self.ghost_src, self.ghost_wall = src[:total], wall[:total]
        self.stages = stages
        self._rows(n + total)

    def build(self) -> None:
        """Choose the ghosts and rebuild the neighbour list on the device (the module's
        docstring)."""
        if self.max_stretch > 1.0:
            self._stretch()
        self._select_ghosts()
        self._fill()
        n, dim, s = self.n + self.n_ghosts, self.dim, self.stream
        x = self.ext["x"]
        key = self._scratch("key", n, np.int64, None, self.out["drho"])
        xs = self._scratch("xs", n, np.float64, dim, self.out["dv"])  # the sorted positions
        lo, hi = self._buffer("lo", dim, np.float64), self._buffer("hi", dim, np.float64)
        lo.copy_to_device(np.full(dim, np.inf), stream=s)
        hi.copy_to_device(np.full(dim, -np.inf), stream=s)
        self._launch("bounds", n, n, x, lo, hi)
        lo_h, hi_h = self._fetch(lo), self._fetch(hi)
        radius = self.radius
        ncell = np.array([max(1, int((hi_h[a] - lo_h[a]) / radius) + 1) for a in range(dim)],
                         dtype=np.int64)
        n_cells = int(np.prod(ncell))
        self.n_cells = n_cells
        d_ncell = self._buffer("ncell", dim, np.int64)
        d_ncell.copy_to_device(ncell, stream=s)
        counts = self._buffer("cell_counts", n_cells, np.int64)
        fill = self._buffer("cell_fill", n_cells, np.int64)
        self._launch("zero", n_cells, counts)
        self._launch("zero", n_cells, fill)
        self._launch("cell", n, n, x, lo, radius, d_ncell, key, counts, self.reference)
        ends = self._buffer("cell_ends", n_cells, np.int64)
        ends.copy_to_device(counts, stream=s)
        self._scan(ends, n_cells)
        order = self._buffer("order", n, np.int32)
        self._launch("scatter", n, n, key, counts, ends, fill, order)
        self._launch("cell_sort", n_cells, n_cells, counts, ends, order)
        self._launch("gather", n, n, order, x, xs)
        offsets = self._buffer("offsets", n + 1, np.int64)
        self._launch("zero", n + 1, offsets)
        front = radius - self.skin  # the support (2D and 3D rows split there, as the CPU's)
        # smoothing lengths that differ (bodies of their own h_over_dx): a radius per pair,
        # as the CPU's list (Solver._build)
        per_pair = (self.per_pair, float(SUPPORT_RADIUS), float(self.skin))
        self._launch("neighbours", n, n, xs, lo, radius, front, d_ncell, counts, ends, offsets,
                     offsets, False, order, self.ext["h"], *per_pair)
        self._scan(offsets[1:], n)
        total = int(self._fetch(offsets[n:])[0])
        indices = self._buffer("indices", total, np.int32)
        self._launch("neighbours", n, n, xs, lo, radius, front, d_ncell, counts, ends, offsets,
                     indices, True, order, self.ext["h"], *per_pair)
        self.order, self.offsets, self.indices = order, offsets, indices
        if self.planes.shape[0]:
            self._inverse()
        self.origin.copy_to_device(lo_h, stream=s)
        self.builds += 1
        self._list_builds += 1

    def _stretch(self) -> None:
        """(ST-1) on the device before a rebuild, over the old list and its ghosts (their
        rows mirrored stage by stage from the positions now), as
        :meth:`impactsph.solver.Solver._build`: the smoothing lengths, then the support,
        skin and radius of the list to come."""
        n, dim = self.n, self.dim
        rows = n + self.n_ghosts
        sx = self._buffer("stretch_x", rows, np.float64, dim)
        sx0 = self._buffer("stretch_x0", rows, np.float64, dim)
        sb = self._buffer("stretch_body", rows, np.int64)
        sh = self._buffer("stretch_h", rows, np.float64)
        c = self.const
        self._launch("stretch_rows", n, n, self.now["position"], c["initial_position"],
                     c["body"], c["smoothing_length"], sx, sx0, sb, sh)
        for first, last in self.stages:  # (a corner image after its source ghost)
            self._launch("stretch_mirror", last - first, first, last, n, sx, sx0, sb, sh,
                         self.ghost_src, self.ghost_wall, self.points, self.normals,
                         self.kinds)
        h = c["smoothing_length"]
        self._launch("stretch", rows, rows, n, self.order, self.offsets, self.indices, sx,
                     sx0, sb, sh, self.h_reference, self.max_stretch, h)
        largest = self._buffer("h_largest", 1, np.float64)
        largest.copy_to_device(np.array([-np.inf]), stream=self.stream)
        self._launch("largest", n, n, h, largest)
        self.support = SUPPORT_RADIUS * float(self._fetch(largest)[0])
        self.skin = self.skin_fraction * self.support
        self.radius = float(self.support + self.skin)
        if self.walls is not None:  # the particles' rows of the extended arrays
            self.ext["h"][:n].copy_to_device(h, stream=self.stream)

    # -- one step ------------------------------------------------------------------------------
    def _evaluate(self, dt: float, weight: float, first: bool, time: float | None,
                  heating: bool = True) -> None:
        """The rates at the device state, of time ``time``; the powers and the walls' push
        booked with ``dt`` times ``weight`` (the evaluation's in the step's mean rate);
        ``first``: the step's first evaluation.  With a viscosity switch, the factors for
        the next evaluation (set at ``time``: :meth:`impactsph.solver.Solver.rates`; None:
        the switches' clock does not move).  ``heating`` False: its viscous heating is not
        booked (the compatible energy update's corrector: its work pass books its own)."""
        if self._stale():
            self.build()
        else:
            self._fill()
        (particle_kernel, pair_kernel, correction_kernel, hourglass_kernel, moment_kernel,
         friction_kernel, switch_kernel, gradient_kernel, force_correction, reconstruction,
         _) = self.rate_kernels
        self.viscosity.check_compiled(reconstruction, self.options.viscosity_factor)
        n, tpb, s = self.n, self.tpb, self.stream
        rows = n + self.n_ghosts
        blocks = max(1, (rows + tpb - 1) // tpb)
        ext, out, P = self.ext, self.out, self.packed
        order, offsets, indices = self.order, self.offsets, self.indices
        particle_kernel[blocks, tpb, s](
            rows, order, ext["x"], ext["v"], ext["m"], ext["rho"], ext["e"], ext["S"],
            ext["carried"], ext["h"], ext["body"], ext["material"], self.table, P)
        mirror = self.planes.shape[0] > 0 and self.n_ghosts > 0  # (the CPU's after_*)
        cols = self.columns
        if force_correction:
            moment_kernel[blocks, tpb, s](rows, P, offsets, indices)
            if mirror:
                self._mirror("mirror_matrices", P, cols.CM0)
        if reconstruction:
            gradient_kernel[blocks, tpb, s](rows, P, offsets, indices)
            if mirror:
                self._mirror("mirror_matrices", P, cols.LV0)
        pair_kernel[blocks, tpb, s](
            rows, n, order, P, offsets, indices, int(self.viscosity.kind), self.viscosity.pair,
            self.options.normal_stress, ext["S"], ext["material"], self.table,
            out["drho"], out["dv"], out["de"], out["de_visc"], out["contact_force"],
            out["pair_count"], out["dS"], out["gradients"])
        if self.compatible and not first:  # the corrector's pair energy rates alone (the
            self.de_pairs.copy_to_device(out["de"], stream=s)  # work pass's baseline)
        if mirror:
            self._mirror("mirror_results", P, cols.U, out["gradients"])
        if self.friction > 0.0:  # (the CPU's order: pairs, friction, correction, hourglass)
            friction_kernel[blocks, tpb, s](
                rows, n, order, P, offsets, indices, int(self.viscosity.kind),
                self.viscosity.pair, self.friction, int(self.n_bodies),
                self.options.normal_stress, out["dv"], out["de"], out["contact_force"])
        if self.corrected:
            correction_kernel[blocks, tpb, s](
                rows, n, order, P, offsets, indices, int(self.viscosity.kind),
                self.viscosity.correction, out["correction_books"], out["dv"], out["de"])
        if self.switched:  # (over the whole list, as the correction: the same sums)
            sw = self.switch
            switch_kernel[blocks, tpb, s](
                rows, n, order, P, offsets, indices, int(self.viscosity.kind),
                self.viscosity.switch,
                0.0 if time is None else max(time - self.factor_time, 0.0),
                sw["next_factor"], sw["next_memory"])
            sw["factor"], sw["next_factor"] = sw["next_factor"], sw["factor"]
            sw["memory"], sw["next_memory"] = sw["next_memory"], sw["memory"]
            if time is not None:
                self.factor_time = time
        if self.hourglass > 0.0:
            hourglass_kernel[blocks, tpb, s](
                rows, n, order, P, out["gradients"], offsets, indices, ext["material"],
                self.table, self.hourglass, self.now["hourglass_acceleration"], out["dv"],
                out["de"], out["dhg"])
        c = self.const
        if self.mu is not None:  # the walls' friction, then their layer, as the CPU solver
            self._launch("wall_friction", n, n, self.now["position"], self.now["velocity"],
                         c["mass"], c["material"], self.table, out["contact_force"],
                         self.points, self.normals, self.mu, self.support, out["dv"],
                         out["de"], self.friction_force)
        if self.layer > 0.0:  # after the pairs and the correction, as the CPU solver
            self._launch("layer", n, n, self.now["position"], self.now["velocity"], c["mass"],
                         c["material"], self.table, self.rigid_points, self.rigid_normals,
                         float(self.layer), self.per_radian, out["dv"], out["de"],
                         self.layer_force)
        self._launch("totals", n, n, c["mass"], out["de_visc"], out["correction_books"],
                     out["pair_count"], out["contact_force"], self.layer_force,
                     self.friction_force, self.corrected,
                     self.walls is not None,
                     self.totals_part)
        self._launch("totals_finish", 1, self.blocks, self.totals_part, float(dt),
                     float(weight), bool(first), bool(heating), self.books)
        if self.fraction is not None:  # added mass: forces per own mass -> accelerations
            self._launch("scale", n, n, self.fraction, out["dv"])
        self.rate_evaluations += 1

    def _mirror(self, kernel: str, *columns) -> None:
        """A symmetry plane's ghosts take their sources' results mirrored, stage by stage
        (a corner image after its source ghost): the kernel ``mirror_results`` or
        ``mirror_matrices`` with ``columns`` (the records, then the column and the
        gradients)."""
        P, *rest = columns
        for first, last in self.stages:
            self._launch(kernel, last - first, first, last, self.ghost_src, self.ghost_wall,
                         self.normals, self.kinds, self.n, self.position, P, *rest)

    def _stage(self, dt: float, v_rate, share: float, last: bool, start=None) -> None:
        """One forward-Euler stage from ``start`` (the step's start copy by default), then
        the walls' constraint (its impulse with ``share`` in the books, its events counted at
        the ``last`` stage)."""
        st = self.start if start is None else start
        now, c, out = self.now, self.const, self.out
        self._launch("advance", self.n, self.n, dt, st["position"], st["velocity"],
                     st["density"], st["specific_energy"], st["deviatoric_stress"],
                     st["plastic_work"], st["material_state"], st["hourglass_acceleration"],
                     v_rate, out["dv"], out["drho"], out["de"], out["dS"], out["dhg"],
                     c["clamped"], c["material"], self.table, c["smoothing_length"],
                     now["position"], now["velocity"], now["density"], now["specific_energy"],
                     now["deviatoric_stress"], now["plastic_work"], now["material_state"],
                     now["hourglass_acceleration"])
        self._constrain(share, last)

    def _constrain(self, share: float, count_events: bool) -> None:
        """The walls' constraint on the device state: ``share`` times its impulse into the
        books, its events if ``count_events``."""
        if self.walls is None:
            return
        n, now = self.n, self.now
        self._launch("enforce", n, n, now["position"], now["velocity"], self.inertia,
                     self.points, self.normals, self.scratch)
        self._launch("enforce_sums", n, n, self.scratch, self.enforce_part)
        self._launch("enforce_finish", 1, self.blocks, self.enforce_part, bool(count_events),
                     float(share), self.books)

    def _keep(self, into: dict) -> None:
        """The integrated fields of the device state copied into ``into`` (the deviator as
        its six components)."""
        self._launch("start", self.n, self.n, *(self.now[f] for f in INTEGRATED),
                     *(into[f] for f in INTEGRATED))

    def _combine(self, weight: float, share: float) -> None:
        """SSP-RK3's ``y = (1 - weight) y + weight y(t)``, then the walls' constraint with
        the share ``share`` (:meth:`impactsph.integrate.SspRk3Integrator._combine`)."""
        self._launch("combine", self.n, self.n, 1.0 - weight, weight,
                     *(self.now[f] for f in INTEGRATED), *(self.start[f] for f in INTEGRATED))
        self._constrain(share, False)

    def _weigh(self, weight: float, first: bool) -> None:
        """SSP-RK3: the evaluation's accelerations (and, with several bodies, its contact
        force) into the step's means with ``weight``."""
        n = self.n
        if self.mean_dv.shape[0]:  # (read by the clamps' and the driven regions' books)
            self._launch("weigh", n, n, float(weight), bool(first), self.out["dv"],
                         self.mean_dv)
        if self.mean_force.shape[0]:
            self._launch("weigh", n, n, float(weight), bool(first), self.out["contact_force"],
                         self.mean_force)

    def step(self, state: ParticleState, dt: float) -> None:
        """Advance the device state by ``dt`` with the run's integrator (:meth:`_midpoint`
        or :meth:`_ssp_rk3`).  ``state``'s time and step move; its arrays are left as they
        were (:meth:`download`)."""
        if self.integrator == "ssp_rk3":
            self._ssp_rk3(state.time, dt)
        else:
            self._midpoint(state.time, dt)
        self.host_current = False
        state.time += dt
        state.step += 1

    def _midpoint(self, t: float, dt: float) -> None:
        """Table 1's predictor-corrector on the device (as
        :meth:`impactsph.integrate.MidpointIntegrator.step`): rates at t, the half step, rates
        at t + dt/2 (the step's books: the weights (0, 1)), the whole step."""
        self._keep(self.start)
        self._evaluate(dt, 0.0, True, t)
        self._stage(0.5 * dt, self.start["velocity"], 0.0, False)
        self._drive(t + 0.5 * dt)
        self._evaluate(dt, 1.0, False, t + 0.5 * dt, heating=not self.compatible)
        # x(t + dt) = x(t) + dt v(t + dt/2): each thread reads its particle's midpoint
        # velocity before it overwrites it
        self._stage(dt, self.now["velocity"], 1.0, True)
        self._drive(t + dt)
        if self.compatible:
            self._work_pass(dt)
        self._finish(t, dt, self.out["dv"])  # (the corrector's accelerations: the mean)

    def _work_pass(self, dt: float) -> None:
        """The compatible energy update (:meth:`impactsph.solver.Solver.work_rates`, as the
        CPU's midpoint step calls it): the corrector's records with each particle's mean
        velocity over the step in their work velocity columns (a ghost's its source's,
        mirrored as its velocity is), the pair kernel again into the work pass's outputs,
        and ``e += dt (de_work - de_pairs)``; the books take the work pass's viscous heating
        (the corrector's was not booked) and its pairs."""
        n, rows, s, tpb = self.n, self.n + self.n_ghosts, self.stream, self.tpb
        ext, out, wo, c = self.ext, self.out, self.work_out, self.const
        work = self._buffer("work", rows, np.float64, self.dim)
        self._launch("mean_velocity", n, n, self.start["velocity"], self.now["velocity"],
                     work)
        for first, last in self.stages:  # (the ghosts' other fields: the same values again)
            self._launch("ghost_fill", last - first, first, last, self.ghost_src,
                         self.ghost_wall, self.points, self.normals, self.kinds, n, ext["x"],
                         work, ext["rho"], ext["e"], ext["S"], ext["carried"], ext["m"],
                         ext["h"], ext["material"], ext["body"], self.n_bodies)
        self._launch("work_columns", rows, rows, self.order, work, self.packed,
                     int(self.columns.W))
        pair_kernel = self.rate_kernels[1]
        pair_kernel[max(1, (rows + tpb - 1) // tpb), tpb, s](
            rows, n, self.order, self.packed, self.offsets, self.indices,
            int(self.viscosity.kind), self.viscosity.pair, self.options.normal_stress,
            ext["S"], ext["material"], self.table, wo["drho"], wo["dv"], wo["de"],
            wo["de_visc"], wo["contact_force"], wo["pair_count"], wo["dS"], wo["gradients"])
        self._launch("work_energy", n, n, float(dt), wo["de"], self.de_pairs,
                     self.now["specific_energy"])
        none = out["dv"][:0]  # (no walls' push, no correction: their columns stay zero)
        self._launch("totals", n, n, c["mass"], wo["de_visc"], out["correction_books"],
                     wo["pair_count"], wo["contact_force"], none, none, False, False,
                     self.totals_part)
        self._launch("totals_finish", 1, self.blocks, self.totals_part, float(dt), 1.0, False,
                     True, self.books)

    def _ssp_rk3(self, t: float, dt: float) -> None:
        """SSP-RK3 on the device, as :meth:`impactsph.integrate.SspRk3Integrator.step`: three
        forward-Euler stages, each from the state it starts from, and two convex
        combinations with the step's start; the books take the evaluations with the weights
        (1/6, 1/6, 2/3), and the walls' impulse each stage's state with its share in the
        result."""
        weights = integrate.SspRk3Integrator.WEIGHTS
        kept = self.kept
        self._keep(self.start)
        self._evaluate(dt, weights[0], True, t)
        self._weigh(weights[0], True)
        self._stage(dt, self.start["velocity"], 1.0 / 6.0, False)
        self._drive(t + dt)
        self._evaluate(dt, weights[1], False, t + dt)
        self._weigh(weights[1], False)
        self._keep(kept)  # y1
        self._stage(dt, kept["velocity"], 1.0 / 6.0, False, kept)
        self._combine(0.75, 2.0 / 3.0)
        self._drive(t + 0.5 * dt)
        self._evaluate(dt, weights[2], False, None)  # (the clock moved at y1's evaluation)
        self._weigh(weights[2], False)
        self._keep(kept)  # y2, in y1's buffers
        self._stage(dt, kept["velocity"], 2.0 / 3.0, True, kept)
        self._combine(1.0 / 3.0, 1.0)
        self._drive(t + dt)
        self._finish(t, dt, self.mean_dv)

    def _finish(self, t: float, dt: float, mean_dv) -> None:
        """The step's books from its mean accelerations ``mean_dv``: the driven regions'
        reactions and work, the supports' impulse on the clamped particles."""
        self._account(t, dt, mean_dv)
        rows = self.clamped_rows.shape[0]
        if rows:  # the supports' impulse, from the step's mean accelerations
            self._launch("clamp_sums", rows, rows, self.clamped_rows, self.inertia, mean_dv,
                         self.clamp_part)
            self._launch("clamp_finish", 1, self.clamp_part.shape[0], self.clamp_part,
                         float(dt), self.books)

    def _drive(self, t: float) -> None:
        """The driven particles at their prescribed velocities at ``t``."""
        if self.drivers is None:
            return
        for r, (rows, _) in zip(self.drivers.regions, self.driven, strict=True):
            if rows.shape[0]:
                velocity = [*r.velocity(t).tolist(), 0.0, 0.0][:3]
                self._launch("drive", rows.shape[0], rows.shape[0], rows, *velocity,
                             self.now["velocity"])

    def _account(self, t: float, dt: float, mean_dv) -> None:
        """The driven regions' reactions and work over the step from ``t`` on (on the
        device, from the step's mean accelerations ``mean_dv``) and their impulse (on the
        host: the prescribed momentum change), as :meth:`impactsph.driven.Drivers.account`."""
        if self.drivers is None:
            return
        for k, (r, (rows, part)) in enumerate(zip(self.drivers.regions, self.driven,
                                                   strict=True)):
            v0, v1 = r.velocity(t), r.velocity(t + dt)
            change = r.mass * (v1 - v0)
            rate = [*(change / dt).tolist(), 0.0, 0.0][:3]
            # the work at the prescribed velocity at t + dt/2, or with the compatible energy
            # update at the step's mean (Drivers.account's mean_velocity)
            middle = 0.5 * (v0 + v1) if self.compatible else r.velocity(t + 0.5 * dt)
            middle = [*middle.tolist(), 0.0, 0.0][:3]
            n_rows = rows.shape[0]
            self._launch("clamp_sums", n_rows, n_rows, rows, self.inertia, mean_dv, part)
            self._launch("drive_finish", 1, part.shape[0], part, k, *rate, *middle,
                         float(dt), self.reactions, self.drive_work)
            self.drivers.impulse += change
        self._accounted = True

    def fold_drivers(self) -> None:
        """The driven regions' reactions (the last step's) and work, as the device holds
        them, into the host's :class:`~impactsph.driven.Drivers`."""
        if self.drivers is None:
            return
        reactions, work = self._fetch(self.reactions), self._fetch(self.drive_work)
        for k, r in enumerate(self.drivers.regions):  # (none before a step's account)
            if r.name in self.drivers.reaction or self._accounted:
                self.drivers.reaction[r.name] = reactions[k, : self.dim].copy()
        self.drivers.work = float(work[0])

    def _set_drivers(self) -> None:
        """The host's driven regions' reactions and work onto the device (with the
        books)."""
        if self.drivers is None:
            return
        reactions = np.zeros(self.reactions.shape)
        for k, r in enumerate(self.drivers.regions):
            if r.name in self.drivers.reaction:
                reactions[k, : self.dim] = self.drivers.reaction[r.name]
        self.reactions.copy_to_device(reactions, stream=self.stream)
        self.drive_work.copy_to_device(np.array([self.drivers.work]), stream=self.stream)

    def survey(self, courant: float) -> tuple[float, np.ndarray, int]:
        """The CFL step (eq 26), ``(KE, IE, p_x, p_y, p_z)`` and the first bad value's code
        (as :func:`impactsph.integrate._survey_kernel` returns them, and ``6 n + i`` for a
        particle behind a wall), from the device state."""
        n = self.n
        now, c = self.now, self.const
        self._launch("survey", n, n, now["position"], now["velocity"], now["density"],
                     now["specific_energy"], now["deviatoric_stress"],
                     now["material_state"], c["mass"], self.inertia, c["smoothing_length"],
                     c["material"], self.table, self.hourglass, self.points, self.normals,
                     self.survey_part, self.bad)
        self._launch("survey_finish", 1, self.blocks, self.survey_part, float(courant),
                     self.bad, self.survey_out)
        out = self._fetch(self.survey_out)
        return float(out[0]), out[1:6].copy(), int(out[6])
