"""Time integration (``time.integrator``, :data:`INTEGRATORS`): the explicit midpoint
predictor-corrector of Table 1 (docs/modelling.md), the default::

    rates at t            ->  y(t + dt/2) = y(t) + dt/2 ydot(t)        (predictor)
    rates at t + dt/2     ->  y(t + dt)   = y(t) + dt   ydot(t + dt/2)  (corrector)

and the three-stage strong-stability-preserving Runge-Kutta method (:class:`SspRk3Integrator`)
for ``y = (x, v, rho, e, S)``, with the strength model's return map (:mod:`.models.strength`)
after each stage and clamped particles held at zero velocity; one stage of one particle is
:func:`impactsph.physics.passes.advance_particle`.  The step follows the CFL condition
(eq 26): ``dt = cs min_i h_i / (c_i + |v_i|)``, ``cs = 0.3`` in the paper.
"""

from __future__ import annotations

from functools import cache
from types import SimpleNamespace
from typing import Any

import numba as nb
import numpy as np

from .jitcache import njit_variant
from .materials import DAMAGE_KIND, EOS_KIND, HEAT_PER_WORK, STRENGTH_KIND, TableLayout
from .models import DAMAGE, STRENGTH
from .models.columns import PLASTIC_COLUMNS, RETURN_MAP_COLUMNS
from .physics.borrow import borrowed
from .physics.chunked import run_chunked, threads_for
from .physics.options import PassOptions, parallel_default
from .physics.rates import compiled_passes
from .physics.stress_rate import UPPER, store_upper
from .physics.survey import (
    SURVEY_CHUNK,
    SURVEY_START,
    SURVEY_WIDTH,
    fold_stage,
    folded_survey,
    rows_finite,
    store_survey,
    survey_chunks,
    survey_particle,
)
from .state import ParticleState


@cache
def _survey_kernel(dim: int):
    @njit_variant(f"{dim}d", nogil=True, error_model="numpy")
    def survey_share(first, step, n_active, x, v, rho, e, S, m, inertia, h, material, table,
                     hourglass, points, normals, parts, bad_of):  # pragma: no cover (compiled)
        """Share ``first`` of ``step`` of the survey's chunks (a chunked pass,
        :mod:`impactsph.physics.chunked`): each chunk's partial survey into its row of
        ``parts`` and ``bad_of`` (:func:`impactsph.physics.survey.store_survey`).  The
        "numpy" error model is the one numba gave the body of the ``prange`` loop this was (a
        zero or negative density gives an infinite or NaN step, not an exception)."""
        # the arrays without reference counts, as the prange body this was got them
        # (impactsph.physics.borrow): 3-4x the time with them
        x = borrowed(x)
        v = borrowed(v)
        rho = borrowed(rho)
        e = borrowed(e)
        S = borrowed(S)
        m = borrowed(m)
        inertia = borrowed(inertia)
        h = borrowed(h)
        material = borrowed(material)
        table = borrowed(table)
        points = borrowed(points)
        normals = borrowed(normals)
        parts = borrowed(parts)
        bad_of = borrowed(bad_of)
        n_chunks = survey_chunks(n_active)
        for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
            acc = SURVEY_START
            lo, hi = chunk * SURVEY_CHUNK, min((chunk + 1) * SURVEY_CHUNK, n_active)
            checked = rows_finite(lo, hi, x, v, rho, e, S)
            for i in range(lo, hi):
                acc = survey_particle(i, n_active, x, v, rho[i], rho, e, S, m,
                                      inertia[i], h, material, table, hourglass, points,
                                      normals, acc, checked)
            store_survey(acc, parts, bad_of, chunk)

    def survey(n_active: int, x: np.ndarray, v: np.ndarray, rho: np.ndarray, e: np.ndarray,
               S: np.ndarray, m: np.ndarray, inertia: np.ndarray, h: np.ndarray,
               material: np.ndarray, table: np.ndarray, courant: float, hourglass: float,
               points: np.ndarray, normals: np.ndarray) -> tuple[float, np.ndarray, int]:
        """One pass over the state: the CFL step (eq 26, with the hourglass control's
        signal speed added where ``hourglass`` (zeta) > 0:
        :data:`impactsph.physics.survey.HOURGLASS_SPEED`), kinetic
        energy and momentum (of ``inertia``, the mass with the added mass), internal
        energy (of ``m``), and the first bad value (``rho``: the material density).  Returns
        ``(dt, sums, bad)``: ``sums = (KE, IE, p_x, p_y, p_z)``; ``bad = field * n + i`` for
        the first particle ``i`` of the first field (0 position, 1 velocity, 2 density, 3
        specific energy, 4 deviatoric stress: non-finite; 5 density: not positive; 6 behind
        one of the planes ``points``, ``normals``: the walls and symmetry planes) that is
        bad, or -1.  Partial sums per chunk of particles, run in shares on numba's threads
        where the passes are threaded (:func:`impactsph.physics.options.parallel_default`)
        and added in a fixed order (:mod:`impactsph.physics.survey`): the result does not
        depend on the threads, and is the one the integrator's last stage gives
        (:meth:`MidpointIntegrator.step`).  (A ``prange`` kernel until 2026-12-06: numba
        typed and compiled its loop's body a second time, 2.9 of its 4.9 s to compile; in
        shares 1.9 s, and some 10 us more a call on a small run, 24 us against 12-16 us on
        the Taylor bar, where numba types the share's 18 arguments.)"""
        n_chunks = survey_chunks(n_active)
        # (NaN: a chunk that no share wrote would show in the sums)
        parts = np.full((n_chunks + 1, SURVEY_WIDTH), np.nan)
        bad_of = np.full(n_chunks + 1, -1, dtype=np.int64)
        run_chunked(survey_share, threads_for(n_active, SURVEY_CHUNK, parallel_default()),
                    n_active, x, v, rho, e, S, m, inertia, h, material, table,
                    float(hourglass), points, normals, parts, bad_of)
        # the chunks folded in chunk order by the stage's own fold (no walls' rows)
        fold_stage(n_active, np.zeros((n_chunks + 1, 1 + dim)), True, parts, bad_of)
        step, sums, bad = folded_survey(parts, bad_of)
        return courant * step, sums, bad

    return survey


def stage_options(table: np.ndarray, plane_stress: bool = False,
                  axisymmetric: bool = False) -> PassOptions:
    """The options of the passes' module whose stage a run of the material ``table`` and
    2D model runs: the stage depends on no option of the pair passes but the 2D model and
    the strength models with a return map, the damage models with an update and the
    equations of state that the table's rows use (``strength_kinds``, ``damage_kinds``,
    ``eos_kinds``: the module names only these), so one module serves every run of that
    kind."""
    strength, damage = list(STRENGTH), list(DAMAGE)
    return PassOptions(
        plane_stress=plane_stress, axisymmetric=axisymmetric,
        strength_kinds=tuple(sorted({int(k) for k in table[:, STRENGTH_KIND]
                                     if strength[int(k)].return_map is not None})),
        damage_kinds=tuple(sorted({int(k) for k in table[:, DAMAGE_KIND]
                                   if damage[int(k)].update is not None})),
        eos_kinds=tuple(sorted({int(k) for k in table[:, EOS_KIND]})))


def material_state_kept(options: PassOptions, width: int, heats: bool = True) -> int:
    """How many of the material state's first columns (of its ``width``) a stage of the
    passes' module of stage ``options`` (:func:`stage_options`) changes, and so how many the
    integrator keeps in the step's start copy (the stages restore those and leave the rest,
    which no stage writes):

    - all of them with a damage model with an update (its own columns are the last),
      plane stress (the thickness ratio), axisymmetry (the radius) or a strength model with
      a state of its own (its block follows the common columns);
    - with a return map and none of those, the first three (:data:`RETURN_MAP_COLUMNS`: the
      equivalent plastic strain, its rate, and the temperature the plastic work heats): the
      damage and the thickness ratio stay as they were set, 16 bytes a particle less (32
      with SSP-RK3's second copy); the first two (:data:`PLASTIC_COLUMNS`) where no
      material that yields ``heats`` (no specific heat, or no Taylor-Quinney factor: the
      stage adds ``beta / c_p`` times the plastic work, 0, to the temperature), 8 bytes
      less again (:func:`state_kept_of_table`);
    - none where no model changes the state (elastic materials, in 1D, plane strain or 3D):
      40 bytes a particle less (the 5 common columns), 80 with SSP-RK3.

    The stage's restore, the step's combination and the device's copies loop over the kept
    columns (the copy's own width), so a prefix serves them all."""
    strength = list(STRENGTH)
    if (options.damage_kinds or options.plane_stress or options.axisymmetric
            or any(strength[k].state for k in options.strength_kinds)):
        return width
    if options.strength_kinds:
        return min(RETURN_MAP_COLUMNS if heats else PLASTIC_COLUMNS, width)
    return 0


def state_kept_of_table(options: PassOptions, table: np.ndarray) -> int:
    """:func:`material_state_kept` for a run of the material ``table`` whose stage has
    ``options`` (:func:`stage_options`): the table's state width, and whether a material
    with a return map heats (its ``beta / c_p``, :data:`HEAT_PER_WORK`, above 0)."""
    strength = list(STRENGTH)
    heats = any(row[HEAT_PER_WORK] > 0.0
                and strength[int(row[STRENGTH_KIND])].return_map is not None for row in table)
    return material_state_kept(options, TableLayout.registered().state_width_of_table(table),
                               heats)


def stable_time_step(state: ParticleState, table: np.ndarray, courant: float,
                     n_active: int | None = None, hourglass: float = 0.0) -> float:
    """CFL step of eq 26 (with the hourglass control's coefficient ``hourglass``, if on)."""
    survey = _survey_kernel(state.dim)
    n = state.n if n_active is None else n_active
    # the material's density (plane stress and axisymmetry keep a mass per area in density)
    no_planes = np.zeros((0, state.dim))
    dt, _, _ = survey(n, state.position, state.velocity, state.material_density,
                      state.specific_energy,
                      state.deviatoric_stress, state.mass, state.inertial_mass,
                      state.smoothing_length,
                      state.material, table, courant, float(hourglass), no_planes, no_planes)
    return float(dt)


@nb.njit(parallel=True, cache=True)
def keep_upper(S, out) -> None:
    """``out[i]``: the six components ``(xx, xy, xz, yy, yz, zz)`` of each particle's deviator
    ``S[i]`` (the integrator's start copy; 2.3-3.4 us for the paper's Taylor bar against
    6.2 us for ``np.take``, and half its time at 1e5 particles on two threads)."""
    for i in nb.prange(S.shape[0]):
        store_upper(S, out, i)


@nb.njit(inline="always", cache=True)
def combine_particle(i, keep, weight, x, v, rho, e, S, plastic_work, state, hg, x0, v0, rho0,
                     e0, S0, pw0, state0, hg0) -> None:
    """``y = keep y + weight y0`` for every integrated field of particle ``i`` (``keep = 1 -
    weight``), ``y0`` the kept copy (its deviator ``S0`` as six components,
    :data:`~impactsph.physics.stress_rate.UPPER`): one particle of :func:`combine_kept`, and
    of the device's SSP-RK3 step (:mod:`impactsph.gpu_step`)."""
    for a in range(x.shape[1]):
        x[i, a] = x[i, a] * keep + weight * x0[i, a]
        v[i, a] = v[i, a] * keep + weight * v0[i, a]
    rho[i] = rho[i] * keep + weight * rho0[i]
    e[i] = e[i] * keep + weight * e0[i]
    for a in range(3):
        for b in range(3):
            S[i, a, b] = S[i, a, b] * keep + weight * S0[i, UPPER[a][b]]
    plastic_work[i] = plastic_work[i] * keep + weight * pw0[i]
    for c in range(state0.shape[1]):  # (the kept columns: those a model changes)
        state[i, c] = state[i, c] * keep + weight * state0[i, c]
    for a in range(hg.shape[1]):
        hg[i, a] = hg[i, a] * keep + weight * hg0[i, a]


@nb.njit(cache=True)
def combine_kept(weight, x, v, rho, e, S, plastic_work, state, hg, x0, v0, rho0, e0, S0, pw0,
                 state0, hg0) -> None:
    """``y = (1 - weight) y + weight y0`` for every integrated field of every particle, ``y0``
    the kept copy (its deviator ``S0`` as six components,
    :data:`~impactsph.physics.stress_rate.UPPER`): the SSP-RK3 step's
    convex combinations, in one loop (:func:`combine_particle` a particle), with numpy's
    roundings (``y *= 1 - weight; y += weight * y0``: two products and a sum, not fused), so
    the same bits as the three numpy operations a field it replaces, without their
    temporaries (about 190 us a step of the Taylor bar's 2.3 ms, in two calls)."""
    keep = 1.0 - weight
    for i in range(x.shape[0]):
        combine_particle(i, keep, weight, x, v, rho, e, S, plastic_work, state, hg, x0, v0,
                         rho0, e0, S0, pw0, state0, hg0)


def run_stage(stage_pass: Any, threaded: bool, n_active: int, *arguments: Any) -> None:
    """One integrator stage of ``n_active`` particles: ``stage_pass`` (a generated module's
    :func:`impactsph.physics.passes.stage`, a chunked pass) called with ``(n_active,
    *arguments)`` in shares on numba's threads where ``threaded``
    (:func:`impactsph.physics.chunked.run_chunked`, a share a chunk of :data:`SURVEY_CHUNK`
    particles at most), then its chunks' wall rows and surveys folded in chunk order
    (:func:`impactsph.physics.survey.fold_stage`): the same bits whatever the thread count."""
    run_chunked(stage_pass, threads_for(n_active, SURVEY_CHUNK, threaded), n_active,
                *arguments)
    # the stage's last arguments: walls, survey, m, hourglass, surveyed, bad_of
    walls, survey, surveyed, bad_of = arguments[-6], arguments[-5], arguments[-2], arguments[-1]
    fold_stage(n_active, walls, survey, surveyed, bad_of)


class MidpointIntegrator:
    """Table 1's predictor-corrector.  ``rates(state)`` must return
    ``(dv, drho, de, dS, dhg)`` for the active particles, ``dS`` the deviator's rate as its six
    components ``(n, 6)``; see :class:`~impactsph.solver.Solver`."""

    #: the weight of each rate evaluation of a step in the step's mean rate (``y(t + dt) =
    #: y(t) + dt sum_k w_k ydot_k``): the powers, wall forces and reactions booked for the step
    #: are the same mean of each evaluation's
    WEIGHTS: tuple[float, ...] = (0.0, 1.0)

    def __init__(self, rates, table: np.ndarray, n_active: int, dim: int, walls=None,
                 drivers=None, plane_stress: bool = False, axisymmetric: bool = False,
                 observe=None, work=None, hourglass: float = 0.0):
        self.rates = rates
        #: ``work(state, mean_velocity)``: the compatible energy update's correction to the
        #: last evaluation's specific-energy rates (:meth:`impactsph.solver.Solver.work_rates`),
        #: or None (the paper's update: ``e`` advanced with its rates, eq 28)
        self.work = work
        self._mean_velocity: np.ndarray | None = None
        #: ``observe(k, weight)``, called after the step's ``k``-th rate evaluation with its
        #: weight in :data:`WEIGHTS` (the run's books: heating, wall impulse), or None
        self.observe = observe
        #: the driven regions (:class:`impactsph.driven.Drivers`), or None
        self.drivers = drivers
        #: the walls and symmetry planes (:class:`impactsph.boundaries.Walls`), whose
        #: constraint follows each stage in the stage's own pass, or None
        self.walls = walls if walls is not None and len(walls) else None
        #: the planes' points and normals, ``(n_planes, dim)`` each (no rows without walls)
        self.planes = ((walls.points, walls.normals) if self.walls is not None
                       else (np.zeros((0, dim)), np.zeros((0, dim))))
        self.constraint_events = 0
        self.constraint_impulse = np.zeros(dim)
        # impulse of the supports that hold clamped particles: minus what the forces on them
        # would have given them
        self.clamp_impulse = np.zeros(dim)
        self.table = table
        self.n_active = n_active
        #: the options of the passes' module whose stage this integrator runs
        self.stage_options = stage_options(table, plane_stress, axisymmetric)
        #: how many of the material state's first columns the step's start copy keeps
        #: (:func:`material_state_kept`: those a stage changes)
        self.material_state_kept = state_kept_of_table(self.stage_options, table)
        self._stage_pass = compiled_passes(dim, options=self.stage_options).stage
        self.survey_kernel = _survey_kernel(dim)
        #: the hourglass control's zeta, which the survey's signal speed includes
        self.hourglass = float(hourglass)
        # the stage's partial results per chunk: the walls' (moved, impulse) and the survey's
        # (and after them the folded row)
        chunks = survey_chunks(n_active) + 1
        self._wall_parts = np.zeros((chunks, 1 + dim))
        self._survey_parts = np.zeros((chunks, SURVEY_WIDTH))
        self._bad_of = np.zeros(chunks, dtype=np.int64)
        #: the survey of the state the last step left, made by its last stage (the midpoint
        #: step without drivers or the compatible energy update, whose work follows the
        #: stage): ``(dt, sums, bad)`` as :func:`_survey_kernel`'s, ``dt`` before the Courant
        #: number; None if that step made none.  :meth:`take_survey` hands it out once.
        self.last_survey: tuple[float, np.ndarray, int] | None = None
        self._any_clamped: bool | None = None
        #: the clamped particles' rows and their inertia, for the supports' impulse
        #: (:meth:`_first_step`)
        self._clamped_rows = np.zeros(0, dtype=np.int64)
        self._clamped_inertia = np.zeros(0)
        self._inertia: np.ndarray | None = None
        self._start: SimpleNamespace | None = None

    #: the fields the integrator advances (the rest of the state is constant within a step)
    INTEGRATED = ("position", "velocity", "density", "specific_energy", "deviatoric_stress",
                  "plastic_work", "material_state", "hourglass_acceleration")

    def take_survey(self) -> tuple[float, np.ndarray, int] | None:
        """The survey the last step's last stage made (:attr:`last_survey`), once: None
        after it has been taken, or if the step made none."""
        survey, self.last_survey = self.last_survey, None
        return survey

    def _save_start(self, state: ParticleState, copy: bool = True) -> SimpleNamespace:
        """The integrated fields at the start of the step, in buffers reused every step
        (``copy`` False: the buffers only, which the step's first stage fills, ``keep``)."""
        if self._start is None or self._start.position.shape != state.position.shape:
            # the kernels index the columns of the materials' models without bounds checks
            layout = TableLayout.registered()
            width, widest = layout.state_width_of_table(self.table), layout.state_width
            shape = state.material_state.shape
            if shape[0] != state.n or not width <= shape[1] <= widest:
                raise ValueError(f"material_state has shape {shape}; the materials' models "
                                 f"need ({state.n}, k) with {width} <= k <= {widest}")
        return self._keep(state, "_start", copy)

    def _keep(self, state: ParticleState, name: str, copy: bool = True) -> SimpleNamespace:
        """A copy of the integrated fields of ``state`` in the buffers ``name`` (reused while
        the shapes stay; ``copy`` False: the buffers alone); the deviator as its six
        components (the stage's ``S0``: :func:`impactsph.physics.stress_rate.
        jaumann_stress_rate`), which is what it holds: the stages write it symmetric."""
        buf = getattr(self, name, None)
        if buf is None or buf.position.shape != state.position.shape:
            buf = SimpleNamespace(**{f: np.empty_like(getattr(state, f))
                                     for f in self.INTEGRATED if f != "deviatoric_stress"})
            buf.deviatoric_stress = np.empty((state.n, 6))
            # (the columns a stage changes: none where no model does)
            buf.material_state = np.empty((state.n, self.material_state_kept))
            setattr(self, name, buf)
        if not copy:
            return buf
        for f in self.INTEGRATED:
            if f == "material_state":
                np.copyto(buf.material_state, state.material_state[:, :self.material_state_kept])
            elif f != "deviatoric_stress":
                np.copyto(getattr(buf, f), getattr(state, f))
        keep_upper(state.deviatoric_stress, buf.deviatoric_stress)
        return buf

    def _stage(self, state: ParticleState, dt: float, start: SimpleNamespace, rates,
               share: float, last: bool, keep: bool = False, survey: bool = False) -> int:
        """One forward-Euler stage ``y = start + dt ydot``, the positions' rate the state's
        own velocities (each particle's read before the stage overwrites it: with ``keep``,
        the velocity it starts from; else the midpoint step's corrector's midpoint velocity),
        then
        the walls' constraint (its impulse with the share ``share`` in the run's books; its
        events counted if this is the step's ``last`` stage), in one pass
        (:func:`impactsph.physics.passes.stage`): with ``keep``, the state is first copied
        into ``start``, particle by particle; with ``survey``, the result is surveyed
        (:attr:`last_survey`).  Returns the constraint's events."""
        dv, drho, de, dS, dhg = rates
        if dS.ndim != 2 or dS.shape[1] != 6:  # the kernel's error would not say which array
            raise ValueError(f"the rates' dS has shape {dS.shape}; the integrator needs "
                             f"(n, 6): the deviator's rate as its six components (xx, xy, xz, "
                             f"yy, yz, zz), impactsph.physics.stress_rate.jaumann_stress_rate")
        points, normals = self.planes
        walls = self._wall_parts
        # (every stage hands the pass the same arrays but for its start's: a stage of the
        # midpoint step looks its compiled code up by their identities alone,
        # impactsph.physics.chunked._address, 2026-12-06)
        run_stage(self._stage_pass, self.stage_options.parallel, self.n_active, dt, keep,
                  start.position, start.velocity, start.density, start.specific_energy,
                  start.deviatoric_stress, start.plastic_work, start.material_state,
                  start.hourglass_acceleration, state.velocity, dv, drho, de, dS, dhg,
                  state.clamped,
                  state.material, self.table, state.smoothing_length, state.position,
                  state.velocity, state.density, state.specific_energy,
                  state.deviatoric_stress, state.plastic_work, state.material_state,
                  state.hourglass_acceleration, points, normals, self._inertia, walls, survey,
                  state.mass, self.hourglass, self._survey_parts,
                  self._bad_of)
        if survey:
            self.last_survey = folded_survey(self._survey_parts, self._bad_of)
        if self.walls is None:
            return 0
        count = int(walls[-1, 0])  # the chunks' counts and impulses, added in chunk order
        if share != 0.0:
            self.constraint_impulse += share * walls[-1, 1:]
        if last:
            self.constraint_events += count
        return count

    def _constrain(self, state: ParticleState, share: float, count_events: bool) -> int:
        """The walls' constraint on ``state``: ``share`` times its impulse goes to the run's
        books (``share``: the weight of this state in the step's result; the midpoint
        predictor's state is discarded, 0), and its events if ``count_events`` (those of each
        integrator's last stage, so that the counts compare).  Returns the events."""
        if self.walls is None:
            return 0
        count, impulse = self.walls.enforce(state.position, state.velocity, self._inertia)
        if share != 0.0:
            self.constraint_impulse += share * impulse
        if count_events:
            self.constraint_events += count
        return count

    def _rates(self, state: ParticleState, k: int, time: float | None):
        """The ``k``-th rate evaluation of the step, at ``time`` (None: the switches' clock
        does not move), reported to :attr:`observe`."""
        rates = self.rates(state, time=time)
        if self.observe is not None:
            self.observe(k, self.WEIGHTS[k])
        return rates

    def _compatible_energy(self, state: ParticleState, start: SimpleNamespace,
                           dt: float) -> None:
        """The compatible energy update (``time.energy_update = "compatible"``): the
        specific energies advanced with the corrector's pair forces' work at each particle's
        mean velocity over the step, ``(v(t) + v(t + dt)) / 2`` (walls, drivers and clamps
        included), instead of at its midpoint velocity.  With ``v(t + dt) = v(t) + dt a``
        the kinetic energy gained is ``sum_i m_i vbar_i . a_i dt``, which the pair forces'
        share of the internal energy now loses exactly (docs/modelling.md)."""
        if self._mean_velocity is None or self._mean_velocity.shape != state.velocity.shape:
            self._mean_velocity = np.empty_like(state.velocity)
        mean = self._mean_velocity
        np.add(start.velocity, state.velocity, out=mean)
        mean *= 0.5
        state.specific_energy += dt * self.work(state, mean)

    def _first_step(self, state: ParticleState) -> None:
        """What the steps of a run keep from its first: the masses the impulses take
        (:attr:`~impactsph.state.ParticleState.inertial_mass`: mass + added mass, impulses
        = inertia dv) and the clamped particles' rows and inertia (the supports' impulse,
        :meth:`_clamp_impulse`)."""
        self._inertia = state.inertial_mass
        self._clamped_rows = np.flatnonzero(state.clamped)
        self._clamped_inertia = self._inertia[self._clamped_rows]
        self._any_clamped = self._clamped_rows.size > 0

    def inertia(self, state: ParticleState) -> np.ndarray:
        """The masses with the added masses that the run's steps take, kept from its first
        step (one array for the survey and the history too, not ``mass + added`` at each
        call); ``state``'s before it (:attr:`~impactsph.state.ParticleState.inertial_mass`:
        the masses themselves where none is added)."""
        return self._inertia if self._inertia is not None else state.inertial_mass

    def _clamp_impulse(self, dt: float, dv: np.ndarray) -> None:
        """The supports' impulse over ``dt``: minus what the step's mean accelerations
        ``dv`` would have given the clamped particles (the clamped rows taken by index, not by
        a mask over every particle: 1.9 us against 4.3 us on the cantilever, the same bits)."""
        self.clamp_impulse -= dt * (self._clamped_inertia @ dv[self._clamped_rows])

    def step(self, state: ParticleState, dt: float) -> None:
        """Advance ``state`` by ``dt`` in place."""
        if self._any_clamped is None:
            self._first_step(state)
        self.last_survey = None
        # the start's copy is made by the predictor's stage (the first rate evaluation
        # changes none of the integrated fields)
        start = self._save_start(state, copy=False)
        drivers = self.drivers
        # the predictor's state is discarded: its constraint's impulse has no share
        self._stage(state, 0.5 * dt, start, self._rates(state, 0, state.time), 0.0, False,
                    keep=True)
        if drivers is not None:
            drivers.apply(state.velocity, state.time + 0.5 * dt)
        rates = self._rates(state, 1, state.time + 0.5 * dt)
        # x(t + dt) = x(t) + dt v(t + dt/2): the kernel reads each particle's midpoint
        # velocity before it overwrites it, so the velocity array itself is the position rate.
        # The stage surveys its result unless something follows it that changes the state
        self._stage(state, dt, start, rates, 1.0, True,
                    survey=drivers is None and self.work is None)
        if drivers is not None:
            drivers.apply(state.velocity, state.time + dt)
            drivers.account(self._inertia, rates[0][: state.n], state.time, dt,
                            mean_velocity=self.work is not None)
        if self.work is not None:
            self._compatible_energy(state, start, dt)
        if self._any_clamped:
            self._clamp_impulse(dt, rates[0])
        state.time += dt
        state.step += 1


class SspRk3Integrator(MidpointIntegrator):
    """The three-stage, third-order strong-stability-preserving Runge-Kutta method (Shu &
    Osher 1988, J. Comput. Phys. 77:439, eq 2.18; Gottlieb & Shu 1998, Math. Comp. 67:73),
    ``time.integrator = "ssp_rk3"``::

        y1      = y(t) + dt ydot(y(t))                              (rates at t)
        y2      = 3/4 y(t) + 1/4 (y1 + dt ydot(y1))                 (rates at t + dt)
        y(t+dt) = 1/3 y(t) + 2/3 (y2 + dt ydot(y2))                 (rates at t + dt/2)

    Each bracket is one forward-Euler stage of :func:`~impactsph.physics.passes.advance_particle`
    (the return map and damage included, from the stage's own start), and each combination a
    convex one of every integrated field, so a positive density stays positive (for a
    stress and its yield surface, below).  The step's mean rate is ``(ydot(y(t)) +
    ydot(y1)) / 6 + 2/3 ydot(y2)`` (:data:`WEIGHTS`).

    Why: on an undamped oscillation ``y' = i omega y`` the midpoint step multiplies the
    amplitude by ``|G|`` with ``|G|^2 = 1 + z^4/4`` (``z = omega dt``), a slow growth that
    nothing but the viscosity removes; this method's ``|G|^2 = 1 - z^4/12 + z^6/36`` is below 1
    for ``z < sqrt(3)``.  Three evaluations a step instead of two: at Courant number ``1.5 cs``
    it costs what the midpoint step costs at ``cs`` (docs/dissipation.md, "The switches'
    energy errors").  The viscosity switches' clock moves once a step, by ``dt``, at the second
    evaluation (the state ``y1`` at ``t + dt``); the first (at ``t``, where the clock already
    is) and the third (the half-step state ``y2``, earlier than ``y1``) set the factors without
    time passing, so Morris-Monaghan's and Cullen-Dehnen's factors move once a step.
    ``ac_optimised``, which optimises over the time to the next evaluation, is refused with
    this integrator.  The convex combinations keep a stress inside a convex yield surface
    whose size is fixed; with hardening, softening or damage the combined yield stress is
    the combination of the stages', close to but not exactly the combined state's.
    """

    WEIGHTS = (1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0)

    def _combine(self, state: ParticleState, start: SimpleNamespace, weight: float,
                 share: float) -> None:
        """``y = (1 - weight) y + weight y(t)`` for every integrated field
        (:func:`combine_kept`), then the walls' constraint, whose impulse has the share
        ``share`` in the step's result (a plane wall's half-space is convex: a combination
        of two states that keep to it does too, and the constraint finds nothing to do)."""
        combine_kept(weight, *(getattr(state, f) for f in self.INTEGRATED),
                     *(getattr(start, f) for f in self.INTEGRATED))
        self._constrain(state, share, False)

    def step(self, state: ParticleState, dt: float) -> None:
        """Advance ``state`` by ``dt`` in place."""
        if self._any_clamped is None:
            self._first_step(state)
        # each stage copies the state it starts from into its buffers, particle by particle
        # (``keep``): a rate evaluation changes none of the integrated fields
        start = self._save_start(state, copy=False)
        drivers = self.drivers
        t = state.time
        books = drivers is not None or self._any_clamped
        # the walls' constraint acts on each stage's state; its impulse reaches the result
        # with that state's share in it: y1 1/6, the second stage 1/6, y2 and the third
        # stage 2/3, the result 1
        rates = self._rates(state, 0, t)
        mean_dv = self.WEIGHTS[0] * rates[0][: state.n] if books else None
        self._stage(state, dt, start, rates, 1.0 / 6.0, False, keep=True)
        if drivers is not None:
            drivers.apply(state.velocity, t + dt)
        y1 = self._keep(state, "_y1", copy=False)
        rates = self._rates(state, 1, t + dt)
        if books:
            mean_dv += self.WEIGHTS[1] * rates[0][: state.n]
        self._stage(state, dt, y1, rates, 1.0 / 6.0, False, keep=True)
        self._combine(state, start, 0.75, 2.0 / 3.0)
        if drivers is not None:
            drivers.apply(state.velocity, t + 0.5 * dt)
        rates = self._rates(state, 2, None)
        if books:
            mean_dv += self.WEIGHTS[2] * rates[0][: state.n]
        # y2 kept in y1's buffers (y1 is read no more): the second and third stages hand the
        # stage pass the same arrays
        self._stage(state, dt, y1, rates, 2.0 / 3.0, True, keep=True)
        self._combine(state, start, 1.0 / 3.0, 1.0)
        if drivers is not None:
            drivers.apply(state.velocity, t + dt)
            drivers.account(self._inertia, mean_dv, t, dt)
        if self._any_clamped:
            self._clamp_impulse(dt, mean_dv)
        state.time += dt
        state.step += 1


#: ``time.integrator``: the name of each time integrator and its class.
INTEGRATORS: dict[str, type[MidpointIntegrator]] = {
    "midpoint": MidpointIntegrator,
    "ssp_rk3": SspRk3Integrator,
}
