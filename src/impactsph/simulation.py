"""The run loop: time stepping, diagnostics, snapshots, probes and failure detection."""

from __future__ import annotations

import logging
import math
import numbers
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from .boundaries import SYMMETRY, walls_of
from .config import Case
from .devices import select_backend
from .driven import Drivers
from .errors import DeviceMemoryError, SimulationError
from .gauges import Gauges
from .integrate import INTEGRATORS
from .jitcache import CompileTimer
from .loading import validated_again
from .materials import carried_von_mises
from .models import VISCOSITY
from .models.columns import COMMON_STATE, DAMAGE
from .physics.options import PassOptions
from .physics.rates import ViscositySettings
from .problem import Problem, build_problem
from .solver import Solver
from .state import ParticleState
from .threads import ThreadGovernor
from .tl_solver import TotalLagrangianSolver

log = logging.getLogger(__name__)


@dataclass
class Snapshot:
    """The particle state at one time."""

    time: float
    fields: dict[str, np.ndarray]


@dataclass
class RunRecord:
    """What a run has produced so far."""

    history: list[dict[str, float]] = field(default_factory=list)
    snapshots: list[Snapshot] = field(default_factory=list)
    probes: dict[str, list[tuple[float, np.ndarray]]] = field(default_factory=dict)
    #: rows of ``gauges.csv`` (the time, then the gauges' columns: :class:`~.gauges.Gauges`)
    gauges: list[np.ndarray] = field(default_factory=list)
    wall_seconds: float = 0.0
    #: of ``wall_seconds``, the time numba spent compiling the run's code or loading it from
    #: its disk cache (:class:`~impactsph.jitcache.CompileTimer`): most of a first run's
    #: time, and a short run's loads
    compile_seconds: float = 0.0
    setup_seconds: float = 0.0
    failure: str | None = None
    #: the thread count's changes: (wall seconds into the run, cores other processes held,
    #: new count) (:class:`~.threads.ThreadGovernor`)
    thread_changes: list[tuple[float, float, int]] = field(default_factory=list)
    #: the governor's trials of a smaller thread count (:class:`~.threads.ThreadGovernor`)
    thread_trials: list[dict[str, object]] = field(default_factory=list)
    #: each restart of the run from a checkpoint, in order: the checkpoint's path, its time
    #: (s) and step, the version that wrote it (``impactsph``) and the one that continued it
    #: (``continued_by``): a history that more than one process, or version, made says so
    restarts: list[dict[str, object]] = field(default_factory=list)


@nb.njit(inline="always", cache=True)
def _speed_and_displacement(i, velocity, position, initial_position):
    """Particle ``i``'s ``(|v|^2, |x - x0|^2)``."""
    v2 = 0.0
    u2 = 0.0
    for a in range(velocity.shape[1]):
        v2 += velocity[i, a] * velocity[i, a]
        d = position[i, a] - initial_position[i, a]
        u2 += d * d
    return v2, u2


@nb.njit(cache=True)
def body_totals(body, mass, inertia, velocity, specific_energy, plastic_work, position,
                initial_position, n_bodies):  # pragma: no cover (compiled)
    """Per body, in one compiled pass over the particles: kinetic energy (of ``inertia``,
    the mass with the added mass), internal energy,
    plastic work (J) and the largest squared displacement ``|x - x0|^2`` (m^2), as the
    columns of an ``(n_bodies, 4)`` array."""
    out = np.zeros((n_bodies, 4))
    if n_bodies == 1:  # the same sums in scalars: 0.67-0.70 of the time, the same bits
        kinetic = internal = plastic = largest = 0.0
        for i in range(body.shape[0]):
            v2, u2 = _speed_and_displacement(i, velocity, position, initial_position)
            kinetic += 0.5 * inertia[i] * v2
            internal += mass[i] * specific_energy[i]
            plastic += mass[i] * plastic_work[i]
            if u2 > largest:
                largest = u2
        out[0, 0], out[0, 1], out[0, 2], out[0, 3] = kinetic, internal, plastic, largest
        return out
    for i in range(body.shape[0]):
        b = body[i]
        v2, u2 = _speed_and_displacement(i, velocity, position, initial_position)
        out[b, 0] += 0.5 * inertia[i] * v2
        out[b, 1] += mass[i] * specific_energy[i]
        out[b, 2] += mass[i] * plastic_work[i]
        if u2 > out[b, 3]:
            out[b, 3] = u2
    return out


@dataclass
class Survey:
    """The state at a glance (see :meth:`Simulation._survey`)."""

    dt: float  #: s, CFL step of eq 26
    kinetic: float  #: J
    internal: float  #: J
    momentum: np.ndarray  #: N s
    bad: int  #: first bad value, ``field * n + particle``, or -1


@dataclass(frozen=True)
class _RowNames:
    """A run's history columns after the energies, in the row's order (each tuple empty
    where the run has none): per axis the momentum and, with walls, clamps or drivers, the
    external impulse; per driven region its reaction; the walls' push on a single body or
    the contact force on each of several (by axis, then body); each body's energies."""

    momentum: tuple[str, ...]
    external: tuple[str, ...]
    reactions: tuple[tuple[str, tuple[str, ...]], ...]
    wall_contact: tuple[str, ...]
    body_contact: tuple[tuple[str, ...], ...]
    body_energies: tuple[tuple[str, str, str], ...]


class Simulation:
    """A case being run.  ``Simulation(case).run()`` runs it to ``case.time.end``."""

    def __init__(self, case: Case, problem: Problem | None = None,
                 state: ParticleState | None = None):
        """``problem``: a set-up to use instead of building one from the case; ``state``: a
        state to continue from (a restart; the record then starts empty and is expected to be
        filled by the caller, see :func:`impactsph.checkpoint.load_checkpoint`)."""
        case = validated_again(case, "Simulation(case)")
        t0 = _time.perf_counter()
        self.case = case
        self.problem = problem or build_problem(case)
        if self.problem.input_index is not None:
            log.info("the %d particles are numbered in their first neighbour list's order "
                     "(compute.particle_order = %r): the snapshots carry each one's number "
                     "as placed (input_index)", self.problem.state.n,
                     case.compute.particle_order)
        #: each particle's smoothing length at t = 0, the nominal kernel the measures scale
        #: by (with kernel.max_stretch the state's own grows, and a restart's state carries
        #: those of its last list build: a copy then, or a read-only view of the one length
        #: where every particle's is the same, 8 B a particle less; without it h never
        #: changes)
        h0 = self.problem.state.smoothing_length
        self.h_reference = h0
        if case.kernel.max_stretch > 1.0:
            uniform = h0.size > 0 and bool((h0 == h0[0]).all())
            self.h_reference = np.broadcast_to(h0[0], h0.shape) if uniform else h0.copy()
        if state is not None:
            self.problem.state = state
        self._resident = None  # the state on the GPU between steps (gpu_step.ResidentStep)
        self._handed_out = False  # whether `state` was read (by a callback) since it was reset
        #: the thread governor of the last ``run`` call, which the next one resumes
        self._governor: ThreadGovernor | None = None
        #: while ``run`` goes: its start (perf_counter), its compile timer, its governor and
        #: the governor's counts of changes and trials before it (:meth:`record_so_far`)
        self._running: tuple[float, CompileTimer, ThreadGovernor, int, int] | None = None
        self._state: ParticleState = self.problem.state
        self.walls = walls_of(case.boundaries, case.dimension)
        self.solver: Solver | TotalLagrangianSolver
        if case.formulation == "total_lagrangian":
            self.solver = TotalLagrangianSolver(
                self.state, self.problem.table, ViscositySettings.of(case.viscosity),
                walls=self.walls, hourglass=case.stabilisation.tl_hourglass,
                penalty_stiffness=case.contact.penalty_stiffness,
                penalty_distance=case.contact.penalty_distance,
                hourglass_damping=case.stabilisation.tl_hourglass_damping)
        else:
            self.solver = Solver(self.state, self.problem.table,
                                 ViscositySettings.of(case.viscosity), walls=self.walls,
                                 skin_fraction=case.time.neighbour_skin,
                                 backend=select_backend(
                                     case.compute.device, case.dimension,
                                     PassOptions.of_case(case), cpu_only=_cpu_only(case)),
                                 hourglass=case.stabilisation.hourglass,
                                 wall_layer=case.contact.wall_layer,
                                 max_stretch=case.kernel.max_stretch,
                                 h_reference=self.h_reference)
        scheme = VISCOSITY[case.viscosity.scheme]
        if scheme.switch is None:
            # no switch: the factor is 1 and the memory 0 for good, and no pass reads them;
            # read-only views of one number (16 B a particle less; a write raises)
            n = self.state.n
            self.state.viscosity_factor = np.broadcast_to(np.float64(1.0), (n,))
            self.state.viscosity_memory = np.broadcast_to(np.float64(0.0), (n,))
        else:
            for name in ("viscosity_factor", "viscosity_memory"):
                if not getattr(self.state, name).flags.writeable:  # from a run without one
                    setattr(self.state, name, np.array(getattr(self.state, name)))
            if state is None:  # a fresh start: the viscosity switch's initial factors
                self.state.viscosity_factor[:] = scheme.initial_factor(case.viscosity)
        if not self.state.added_mass.any():
            # no particle carries added mass: a read-only view of one zero (8 B a particle
            # less); the passes and the books read the inertia (ParticleState.inertial_mass:
            # then the masses themselves), never the added masses
            self.state.added_mass = np.broadcast_to(np.float64(0.0), (self.state.n,))
        if case.stabilisation.hourglass > 0.0 and self.state.hourglass_acceleration.shape[1] \
                != self.state.dim:
            self.state.hourglass_acceleration = np.zeros((self.state.n, self.state.dim))
        self.integrator = INTEGRATORS[case.time.integrator](
            self.solver.rates, self.problem.table, self.state.n, self.state.dim,
            walls=self.walls,
            drivers=Drivers.of(case, self.state),
            plane_stress=case.two_dimensional == "plane_stress",
            axisymmetric=case.two_dimensional == "axisymmetric", observe=self._observe,
            work=self._work if case.time.energy_update == "compatible" else None,
            hourglass=float(case.stabilisation.hourglass))
        #: the step's mean powers (AV heating, AC work, AC heating; W) and wall force (N),
        #: the integrator's weights over its rate evaluations (:meth:`_observe`)
        self._step_books = (0.0, 0.0, 0.0, np.zeros(self.state.dim))
        #: the step's mean contact force on each body (several bodies only; N or N/m), by the
        #: same weights (the history's ``contact_force_*``)
        self._body_force = np.zeros((len(self.problem.body_names), self.state.dim))
        self.record = RunRecord(probes={name: [] for name in self.problem.probes})
        self.gauges = Gauges.of(case, self.problem)
        #: per body, the largest displacement |x - x0| of a particle at the history's rows (m)
        self.max_displacement = np.zeros(len(self.problem.body_names))
        self.viscous_dissipation = 0.0  # J, time integral of the AV heating
        self.correction_work = 0.0  # J, work of the AC correction force on the particles
        self.correction_heating = 0.0  # J, internal energy the AC energy term added
        self.wall_impulse = np.zeros(self.state.dim)  # N s, time integral of the walls' push
        self._abs_momentum0 = float(np.sum(self.state.inertial_mass *
                                           np.linalg.norm(self.state.velocity, axis=1)))
        try:
            self.solver.rates(self.state.copy())  # compile (or load from cache) before timing
            self._observe(0, 1.0)  # the start's forces, for the history's first row
            self.solver.pair_evaluations = 0
            self.solver.rate_evaluations = 0
            if self._on_gpu():
                self._keep_on_device()
        except Exception as exc:
            self._stop_if_out_of_device_memory(exc, "while the run was set up")
            raise
        if state is None:
            self._record_row(0.0, self._survey())
            self._take_snapshots(previous=-np.inf)
        self.record.setup_seconds = _time.perf_counter() - t0

    # -- the state on the GPU ------------------------------------------------------------
    @property
    def state(self) -> ParticleState:
        """The particle state.  With the state kept on the GPU between steps
        (:mod:`impactsph.gpu_step`) reading it downloads the device's latest values first (and
        a callback that read it has it uploaded again after it: it may have changed it)."""
        self._handed_out = True
        return self._host_state()

    def _host_state(self) -> ParticleState:
        """The state, downloaded from the GPU if the device's is newer (for this class's own
        readers: not counted as handed out)."""
        if self._resident is not None and not self._resident.host_current:
            self._sync()
        return self._state

    @property
    def time(self) -> float:
        """The simulated time (s), without a download of the state."""
        return self._state.time

    @property
    def step(self) -> int:
        """The steps taken, without a download of the state."""
        return self._state.step

    def _on_gpu(self) -> bool:
        """Whether the run's rates (and perhaps its state) are on a GPU."""
        backend = getattr(self.solver, "backend", None)
        return backend is not None and backend.device == "gpu"

    def _stop_if_out_of_device_memory(self, exc: BaseException, where: str) -> None:
        """If ``exc`` is a GPU's refusal of an allocation (:func:`impactsph.gpu.out_of_memory`),
        raise the :class:`DeviceMemoryError` that says ``where`` (the set-up, a step) and at
        what time, what the run held on the GPU and what it has free now (the record keeps
        it as the run's failure).  A device list the failed rebuild may have left half made
        is not taken back to the host (whose list is that of the last rebuild brought back:
        consistent, if older)."""
        if not self._on_gpu():
            return
        from . import gpu

        if not gpu.out_of_memory(exc):
            return
        from .preflight import _bytes

        s, r = self._state, self._resident
        held = ""
        if r is not None:
            r._list_builds = 0
            total = sum(size for size, _ in r.allocated().values())
            held = (f"; the run held {_bytes(total)} on it ({s.n:,} particles, "
                    f"{r.n_ghosts:,} ghosts, {int(r.indices.shape[0]):,} neighbour-list "
                    f"entries)")
        free, name = gpu.free_memory()
        now = f"; the {name} has {_bytes(free)} free" if free is not None else ""
        error = DeviceMemoryError(
            f"the GPU ran out of memory {where}, at t = {s.time:.6e} s{held}{now}: fewer "
            f"particles, compute.record_precision = \"float32\" or compute.device = "
            f"\"cpu\"", step=s.step, time=s.time, particle=None)
        if hasattr(self, "record"):
            self.record.failure = str(error)
        raise error from exc

    def _keep_on_device(self) -> None:
        """Keep the state on the GPU between steps where the case allows it (else say why:
        its rates still run on the GPU)."""
        from .gpu_step import ResidentStep, resident_unsupported

        why = resident_unsupported(self.case)
        if why is not None:
            log.info("the state stays on the host between steps (%s): its rates run on the "
                     "GPU, with the state copied up and the rates down at each evaluation", why)
            return
        self._resident = ResidentStep(self.solver, self._state, self.problem.table,
                                      self.integrator.drivers, self.case.time.integrator)
        self._resident.set_books(self._books())
        self.solver.backend.release()  # the host path's copies, from the first evaluation
        log.info("the whole step runs on the GPU: the state stays there between steps")

    def _sync(self) -> None:
        """The device's state into the host state, with the books and counters."""
        self._resident.download(self._state)
        self._fold()

    def _books(self) -> dict:
        """The run's books, as :meth:`impactsph.gpu_step.ResidentStep.set_books` takes them."""
        return {"heating": self.viscous_dissipation, "correction_work": self.correction_work,
                "correction_heating": self.correction_heating,
                "pairs": self.solver.pair_evaluations, "wall_impulse": self.wall_impulse,
                "events": self.integrator.constraint_events,
                "constraint_impulse": self.integrator.constraint_impulse,
                "push": self._step_books[3], "clamp_impulse": self.integrator.clamp_impulse}

    def _upload(self) -> None:
        """The host state and books onto the GPU (the caller may have changed them)."""
        self._resident.upload(self._state)
        self._resident.set_books(self._books())

    def _fold(self) -> None:
        """The books as the GPU holds them (its running totals, added in the CPU's order:
        the same bits whenever they are read), and the counters of the steps done there."""
        r = self._resident
        books = r.books_now()
        self.viscous_dissipation = books["heating"]
        self.correction_work = books["correction_work"]
        self.correction_heating = books["correction_heating"]
        self.wall_impulse = books["wall_impulse"]
        self._step_books = (0.0, 0.0, 0.0, books["push"])  # the last step's push (history)
        self.integrator.constraint_events = books["events"]
        self.integrator.constraint_impulse = books["constraint_impulse"]
        self.integrator.clamp_impulse = books["clamp_impulse"]
        r.fold_drivers()
        self.solver.pair_evaluations = books["pairs"]
        self.solver.rate_evaluations += r.rate_evaluations
        self.solver.neighbours.builds += r.builds
        r.rate_evaluations = r.builds = 0

    def _observe(self, k: int, weight: float) -> None:
        """The integrator's ``k``-th rate evaluation of a step, of weight ``weight`` in the
        step's mean rate: its powers and wall force added to the step's books (a weight of 0
        adds nothing, so the midpoint step books its midpoint evaluation's, exactly)."""
        n_bodies = self._body_force.shape[0]
        if k == 0:
            self._step_books = (0.0, 0.0, 0.0, np.zeros(self._state.dim))
            if n_bodies > 1:  # (read for several bodies only)
                self._body_force[:] = 0.0
        if weight == 0.0:
            return
        if n_bodies > 1:
            s = self._state
            force = self.solver.buffers.contact_force[: s.n]
            for a in range(s.dim):
                self._body_force[:, a] += weight * np.bincount(s.body, weights=force[:, a],
                                                               minlength=n_bodies)
        heating, work, corr_heating = self.solver.powers
        books = self._step_books
        self._step_books = (books[0] + weight * heating, books[1] + weight * work,
                            books[2] + weight * corr_heating,
                            books[3] + weight * self.solver.wall_force)

    def _work(self, state: ParticleState, mean_velocity: np.ndarray) -> np.ndarray:
        """The compatible energy update's work pass (:meth:`Solver.work_rates`); the step's
        viscous heating booked is then the heat it put in, not the evaluation's."""
        correction, heating = self.solver.work_rates(state, mean_velocity)
        self._step_books = (heating, *self._step_books[1:])
        return correction

    # -- diagnostics -------------------------------------------------------------------
    def _survey(self) -> Survey:
        """CFL step, energies, momentum and the first bad value of the state, in one pass."""
        s = self._state
        if self._resident is not None:
            dt, sums, bad = self._resident.survey(self.case.time.courant)
            return Survey(dt, float(sums[0]), float(sums[1]), sums[2: 2 + s.dim].copy(), bad)
        made = self.integrator.take_survey()  # the last stage's, where it made one
        if made is not None:
            step, sums, bad = made
            dt = self.case.time.courant * step
        else:
            points, normals = self.integrator.planes
            dt, sums, bad = self.integrator.survey_kernel(
                s.n, s.position, s.velocity, s.material_density, s.specific_energy,
                s.deviatoric_stress, s.mass, self.integrator.inertia(s), s.smoothing_length,
                s.material, self.problem.table, self.case.time.courant, self.integrator.hourglass,
                points, normals)
        # a solver's own limit (the total-Lagrangian hourglass penalty's and walls')
        dt = min(float(dt), self.solver.step_limit(s))
        return Survey(dt, float(sums[0]), float(sums[1]), sums[2: 2 + s.dim].copy(),
                      int(bad))

    def _row_names(self) -> _RowNames:
        """The history row's column names of this run (:class:`_RowNames`), made at its first
        row: the walls, clamps, drivers, bodies and dimension are fixed for the run."""
        names = self.__dict__.get("_names")
        if names is None:
            s = self._state
            axes = "xyz"[: s.dim]
            bodies = self.problem.body_names
            drivers = self.integrator.drivers
            # walls, clamps or driven regions: fixed for the run
            supported = bool(len(self.walls) or s.clamped.any() or drivers is not None)
            walls_push = len(bodies) == 1 and len(self.walls)  # one body: the walls' push
            names = self._names = _RowNames(
                momentum=tuple(f"momentum_{a}" for a in axes),
                external=tuple(f"external_impulse_{a}" for a in axes) if supported else (),
                reactions=tuple((r.name, tuple(f"reaction_force_{r.name}_{a}" for a in axes))
                                for r in drivers.regions) if drivers is not None else (),
                wall_contact=(tuple(f"contact_force_{bodies[0]}_{a}" for a in axes)
                              if walls_push else ()),
                body_contact=(tuple(tuple(f"contact_force_{body}_{a}" for body in bodies)
                                    for a in axes) if len(bodies) > 1 else ()),
                body_energies=(tuple((f"kinetic_energy_{body}", f"internal_energy_{body}",
                                      f"plastic_work_{body}") for body in bodies)
                               if len(bodies) > 1 else ()))
        return names

    def _record_row(self, dt: float, survey: Survey) -> None:
        s = self._state
        names = self._row_names()
        n_bodies = len(self.problem.body_names)
        if self._resident is not None:  # the sums on the GPU: no download of the state
            self._fold()
            device = self._resident.body_totals()
            totals = device[:, :4]
            if n_bodies > 1 and s.step > 0:  # the last step's mean (the device keeps it)
                self._body_force[:] = device[:, 4: 4 + s.dim]
        else:
            totals = body_totals(s.body, s.mass, self.integrator.inertia(s), s.velocity,
                                 s.specific_energy, s.plastic_work, s.position,
                                 s.initial_position, n_bodies)
        row = {"time": s.time, "step": s.step, "dt": dt, "kinetic_energy": survey.kinetic,
               "internal_energy": survey.internal,
               "total_energy": survey.kinetic + survey.internal,
               "viscous_dissipation": self.viscous_dissipation,
               "correction_work": self.correction_work,
               "correction_heating": self.correction_heating}
        # walls, clamps or drivers: their impulse beside the momentum
        external = self.external_impulse() if names.external else None
        for a, name in enumerate(names.momentum):
            row[name] = float(survey.momentum[a])
            if external is not None:
                row[names.external[a]] = float(external[a])
        drivers = self.integrator.drivers
        if drivers is not None:  # the driven regions' reactions and work
            row["external_work"] = drivers.work
            for region, keys in names.reactions:
                force = drivers.reaction.get(region)
                for a, key in enumerate(keys):
                    row[key] = float(force[a]) if force is not None else 0.0
        # the contact forces: the step's mean (for the midpoint step, its midpoint
        # evaluation's), as the books (at the start, the start's)
        push = self._step_books[3]
        for a, key in enumerate(names.wall_contact):  # one body: its force is the walls' push
            row[key] = float(push[a])
        for a, keys in enumerate(names.body_contact):
            for b, key in enumerate(keys):
                row[key] = float(self._body_force[b, a])
        # (one body: its own total, to the bit the sum of one)
        row["plastic_work"] = (float(totals[0, 2]) if n_bodies == 1
                               else float(totals[:, 2].sum()))
        for b, (kinetic, internal, plastic) in enumerate(names.body_energies):
            row[kinetic] = float(totals[b, 0])
            row[internal] = float(totals[b, 1])
            row[plastic] = float(totals[b, 2])
        if n_bodies == 1:  # (np.maximum's: a NaN wins)
            largest, displacement = self.max_displacement[0], math.sqrt(totals[0, 3])
            if displacement > largest or displacement != displacement:
                self.max_displacement[0] = displacement
        else:
            np.maximum(self.max_displacement, np.sqrt(totals[:, 3]),
                       out=self.max_displacement)
        self.record.history.append(row)

    def external_impulse(self) -> np.ndarray:
        """Impulse (N s) given to the particles by walls and clamps since t = 0."""
        i = self.integrator
        driven = i.drivers.impulse if i.drivers is not None else 0.0
        return self.wall_impulse + i.constraint_impulse + i.clamp_impulse + driven

    # -- snapshots and probes ------------------------------------------------------------
    def _snapshot_fields(self) -> dict[str, np.ndarray]:
        s = self._host_state()
        fields = {k: v.copy() for k, v in s.arrays().items()}
        fields["pressure"] = self.solver.pressure(s)
        damage = s.material_state[:, DAMAGE]
        fields["von_mises_stress"] = carried_von_mises(s.deviatoric_stress, damage)
        for k, name in enumerate(COMMON_STATE):
            fields[name] = s.material_state[:, k].copy()
        if self.problem.input_index is not None:  # renumbered (compute.particle_order)
            fields["input_index"] = self.problem.input_index.copy()
        return fields

    def _take_snapshots(self, previous: float) -> None:
        t = self._state.time
        for ts in self.case.output.snapshot_times:
            if previous < ts <= t:
                self.record.snapshots.append(Snapshot(ts, self._snapshot_fields()))
        for name, idx in self.problem.probes.items():
            velocity = (self._state.velocity[idx].copy() if self._resident is None
                        or self._resident.host_current
                        else self._resident.rows(np.atleast_1d(idx)).reshape(
                            self._state.velocity[idx].shape))
            self.record.probes[name].append((t, velocity))
        if self.gauges is not None:  # (on the GPU, the gauges' rows alone come back)
            g, s = self.gauges, self._state
            rows = (g.rows_of(s) if self._resident is None or self._resident.host_current
                    else self._resident.gauge_rows(g.indices))
            self.record.gauges.append(g.sample_rows(t, rows, s.initial_position[g.indices],
                                                    s.material[g.indices], self.problem.table))

    def _next_stop(self, t_end: float) -> float:
        t = self._state.time
        later = [ts for ts in self.case.output.snapshot_times if ts > t * (1 + 1e-12) + 1e-300]
        return min([t_end, *later])

    # -- failure detection ---------------------------------------------------------------
    def _where(self, i: int) -> str:
        s = self._host_state()
        return (f"at step {s.step}, t = {s.time:.6e} s, particle {i} "
                f"(body {self.problem.body_names[s.body[i]]!r}, position {s.position[i].tolist()})")

    #: what :meth:`_survey`'s bad-value code means, by field
    BAD_VALUES = ("non-finite position", "non-finite velocity", "non-finite density",
                  "non-finite specific_energy", "non-finite deviatoric_stress",
                  "non-positive density", "particle crossed a wall")

    def _check(self, survey: Survey, dt0: float) -> None:
        """Stop on a non-finite value, a non-positive density, a particle behind a wall or a
        collapsed step.  Run before every step (and once after the last), so it sees the
        result of the previous step and of any callback."""
        s = self._state
        dt = survey.dt
        if survey.bad >= 0:  # (a particle behind a wall too: the survey's last kind)
            field, i = divmod(survey.bad, s.n)
            raise SimulationError(f"{self.BAD_VALUES[field]} {self._where(i)}", s.step, s.time,
                                  i)
        if dt < 1e-6 * dt0:
            raise SimulationError(f"time step collapsed to {dt:.3e} s (initial {dt0:.3e} s) at "
                                  f"step {s.step}, t = {s.time:.6e} s", s.step, s.time, None)

    #: :meth:`correction_note`: the window of history rows it looks at, and how many times the
    #: correction's largest rate of work over any earlier such window its rate over the last
    #: one must be
    CORRECTION_WINDOW = 50
    CORRECTION_SURGE = 5.0

    def correction_note(self) -> str:
        """Why a run with an acceleration correction (the paper's AC) may have failed: "" or a
        sentence for the failure message.  Eq 34 has no bound: where the smoothed viscous
        acceleration exceeds a particle's own, the correction turns internal energy into
        motion, and the run ends with a collapsed step or a non-finite value
        (docs/dissipation.md, "Why AC's 3D runs blow up").  The note is given when the
        correction's work on the particles (``correction_work``, its last finite values: the
        history rows and the books since the last row) rose over the last
        :data:`CORRECTION_WINDOW` rows by more than 1% of what it was and at more than
        :data:`CORRECTION_SURGE` times the largest rate it had over any earlier window of as
        many rows, after it had been at work for at least one such window."""
        if not getattr(self.solver, "corrected", False):
            return ""
        rows = [(r["time"], r["step"], r["correction_work"]) for r in self.record.history]
        s = self._state
        if not rows or s.step > rows[-1][1]:  # the books since the last row
            rows.append((s.time, s.step, self.correction_work))
        rows = [r for r in rows if math.isfinite(r[2])]
        window = self.CORRECTION_WINDOW
        if len(rows) <= 2 * window:
            return ""
        t, step, work = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
        end = len(rows) - 1
        before = end - window
        active = np.flatnonzero(work != work[0])
        if active.size == 0 or before - active[0] < window:
            return ""
        k = np.arange(active[0] + window, before + 1)
        earlier = np.max((work[k] - work[k - window])
                         / np.maximum(t[k] - t[k - window], 1e-300))
        rise = work[end] - work[before]
        if not (rise > 0.01 * abs(work[before])
                and rise > self.CORRECTION_SURGE * max(earlier, 0.0) * (t[end] - t[before])):
            return ""
        return (f"the acceleration correction's work on the particles rose from "
                f"{work[before]:.4g} J to {work[end]:.4g} J over the last "
                f"{int(step[end] - step[before])} steps, faster than {self.CORRECTION_SURGE:g} "
                f"times its largest rate before: eq 34 can turn internal energy into motion where "
                f"the smoothed viscous acceleration exceeds a particle's own (docs/dissipation.md, "
                f"\"Why AC's 3D runs blow up\"); viscosity.scheme = \"ac_pairwise\" or \"av\" "
                f"holds such runs")

    def _threaded_passes(self) -> bool:
        """Whether the step's passes run on numba's threads (not where
        ``$IMPACTSPH_PARALLEL=0`` compiled them serial)."""
        options = getattr(getattr(self.solver, "backend", None), "options", None)
        return bool(getattr(options, "parallel", True))

    # -- the loop ------------------------------------------------------------------------
    def run(self, t_end: float | None = None,
            callback: Callable[[Simulation], None] | None = None) -> RunRecord:
        """Advance to ``t_end`` (default: the case's end time).  ``callback(sim)`` is called
        after every step; a callback that changes the state reaches it through ``sim.state``
        (reading ``sim.state`` marks it as possibly changed: the next step's CFL step,
        energies and checks are then surveyed again; one that reads only ``sim.time``,
        ``sim.step`` or ``sim.record`` costs no second survey).  Raises
        :class:`SimulationError` if the run goes unstable; the record keeps everything up to
        the last good step.  Refused before any step (:class:`ValueError`,
        :class:`TypeError`): a ``t_end`` that is not a finite number or lies before the
        simulation's time, a ``callback`` that is not callable, and a state array of another
        shape than its particles' (:meth:`~impactsph.state.ParticleState.check_shapes`, also
        after a callback that read the state)."""
        if t_end is not None and (isinstance(t_end, bool | np.bool_)
                                  or not isinstance(t_end, numbers.Real)
                                  or not math.isfinite(t_end)):
            raise ValueError(f"run(t_end = {t_end!r}): a finite time in seconds, or None for "
                             f"the case's time.end")
        t_end = None if t_end is None else float(t_end)  # (a numpy number too)
        if t_end is not None and t_end < self._state.time:
            raise ValueError(f"run(t_end = {t_end!r}): before the simulation's time, "
                             f"t = {self._state.time!r} s; it runs forward only")
        if callback is not None and not callable(callback):
            raise TypeError(f"run(callback = {callback!r}): a function of the simulation, "
                            f"callback(sim), or None")
        self._state.check_shapes()  # (arrays a caller replaced: before any compiled pass)
        t_end = self.case.time.end if t_end is None else t_end
        max_steps = self.case.time.max_steps
        every = self.case.output.history_every
        resident = self._resident
        if resident is not None and resident.host_current:  # the caller may have changed it
            try:
                self._upload()
            except Exception as exc:
                self._stop_if_out_of_device_memory(exc, "as the state was copied to it")
                raise
        s = self._state
        survey = self._survey()
        dt0 = survey.dt
        setting, tune = self.case.compute.threads, resident is None and self._threaded_passes()
        governor = self._governor
        if governor is not None and governor.resumable(setting, tune):
            governor.resume()  # a run in pieces keeps its count and its trials' schedule
        else:
            governor = self._governor = ThreadGovernor(setting, tune=tune)
        changes, trials = len(governor.changes), len(governor.trials)
        compiling = CompileTimer().__enter__()
        start = _time.perf_counter()
        self._running = (start, compiling, governor, changes, trials)
        try:
            while s.time < t_end * (1 - 1e-12):
                governor.tick()
                if max_steps is not None and s.step >= max_steps:
                    break
                dt = survey.dt
                self._check(survey, dt0)
                stop = self._next_stop(t_end)
                reaches_stop = s.time + dt >= stop
                if reaches_stop:
                    dt = stop - s.time
                elif s.time + 1.5 * dt > stop:  # avoid a sliver step before a stop
                    dt = 0.5 * (stop - s.time)
                previous = s.time
                if resident is not None:  # its books stay on the device (:meth:`_sync`)
                    resident.step(s, dt)
                else:
                    self.integrator.step(s, dt)
                    heating, work, corr_heating, wall_force = self._step_books
                    self.viscous_dissipation += dt * heating
                    self.correction_work += dt * work
                    self.correction_heating += dt * corr_heating
                    self.wall_impulse += dt * wall_force
                if reaches_stop:
                    s.time = stop
                survey = self._survey()
                if s.step % every == 0 or s.time >= t_end * (1 - 1e-12):
                    self._record_row(dt, survey)
                self._take_snapshots(previous)
                if callback is not None:
                    self._handed_out = False
                    callback(self)
                    if self._handed_out:  # the callback read the state: it may have changed it
                        s.check_shapes()  # (an array replaced: no pass reads past its end)
                        if resident is not None:
                            self._upload()
                        survey = self._survey()
            self._check(survey, dt0)
        except SimulationError as exc:
            note = self.correction_note()
            if note:
                exc.args = (f"{exc}; {note}", *exc.args[1:])
            self.record.failure = str(exc)
            raise
        except Exception as exc:
            self._stop_if_out_of_device_memory(exc, f"in step {s.step + 1}")
            raise
        finally:
            if resident is not None and not resident.host_current:  # the state back
                self._sync()
            self._add_running(self.record)
            compiling.__exit__()
            self._running = None
            governor.close()
        return self.record

    def record_so_far(self) -> RunRecord:
        """:attr:`record`'s times and threads with those of the ``run`` call going now (a
        checkpoint written during a step: its run's wall time then counts the steps before
        it, which its pair evaluations count too), a copy; :attr:`record` itself outside a
        call."""
        if self._running is None:
            return self.record
        import copy

        record = copy.copy(self.record)
        record.thread_changes = list(record.thread_changes)
        record.thread_trials = list(record.thread_trials)
        self._add_running(record)
        return record

    def _add_running(self, record: RunRecord) -> None:
        """Add the ``run`` call going now to ``record``: its wall and compile time so far, its
        thread changes and trials (at its end, to :attr:`record` itself)."""
        start, compiling, governor, changes, trials = self._running
        record.wall_seconds += _time.perf_counter() - start
        record.compile_seconds += compiling.seconds
        record.thread_changes.extend(governor.changes[changes:])
        record.thread_trials.extend(governor.trials[trials:])

    # -- summary -------------------------------------------------------------------------
    def summary(self) -> dict[str, float | int | str | None]:
        """Run-wide numbers: size, speed, energy and momentum conservation (during a
        ``run`` call, its time so far counted: :meth:`record_so_far`)."""
        record = self.record_so_far()
        h = record.history
        ke = np.array([r["kinetic_energy"] for r in h])
        # the energy the driven regions' supports put in is not an error
        tot = np.array([r["total_energy"] - r.get("external_work", 0.0) for r in h])
        dims = "xyz"[: self.state.dim]
        p = np.array([[r[f"momentum_{a}"] - r.get(f"external_impulse_{a}", 0.0) for a in dims]
                      for r in h])
        # a symmetry plane exchanges the momentum normal to it with the mirrored half: the
        # drift is measured in the directions along every plane
        for w in np.flatnonzero(self.walls.kinds == SYMMETRY):
            n = self.walls.normals[w]
            p = p - np.outer(p @ n, n)
        e0 = tot[0]
        scale = e0  # what the energy errors are relative to
        if "external_work" in h[0]:  # driven regions: the energy they put in counts too
            scale = max(abs(e0), float(np.max(np.abs([r["external_work"] for r in h]))))
        wall = record.wall_seconds
        stepping = wall - record.compile_seconds
        return {
            "n_particles": self.state.n,
            "dimension": self.state.dim,
            "n_steps": self.state.step,
            "t_end": self.state.time,
            "wall_seconds": wall,
            "compile_seconds": record.compile_seconds,
            "setup_seconds": record.setup_seconds,
            "pair_evaluations": self.solver.pair_evaluations,
            # the steps' own rate: numba's compiling and loading of code left out
            "pair_evaluations_per_second": self.solver.pair_evaluations / stepping
            if stepping > 0.0 else 0.0,
            "neighbour_list_builds": self.solver.neighbours.builds,
            "device": self.solver.backend.device,
            # the GPU memory of a run with its state there (its arrays, each once)
            "device_memory_bytes": (sum(size for size, _ in self._resident.allocated().values())
                                    if self._resident is not None else None),
            "thread_changes": [list(c) for c in record.thread_changes],
            "thread_trials": list(record.thread_trials),
            "restarts": list(record.restarts),
            "wall_constraint_events": self.integrator.constraint_events,
            "kinetic_energy_initial": float(ke[0]),
            "kinetic_energy_final": float(ke[-1]),
            "kinetic_energy_ratio_final": float(ke[-1] / ke[0]) if ke[0] > 0 else None,
            "internal_energy_final": float(h[-1]["internal_energy"]),
            "viscous_dissipation": float(h[-1]["viscous_dissipation"]),
            "correction_work": float(h[-1]["correction_work"]),
            "correction_heating": float(h[-1]["correction_heating"]),
            # what the scheme itself adds to or takes from the total energy (0 for AV)
            "energy_imbalance": float((h[-1]["correction_work"] + h[-1]["correction_heating"])
                                      / scale) if scale else 0.0,
            # KE + IE - E0 against what the budget books: the time integration's share
            "energy_budget_residual": float(np.max(np.abs(
                tot - e0 - np.array([r["correction_work"] + r["correction_heating"]
                                     for r in h]))) / scale) if scale else 0.0,
            "total_energy_relative_error": (float(np.max(np.abs(tot - e0)) / scale) if scale
                                            else 0.0),
            "momentum_drift": float(np.max(np.linalg.norm(p - p[0], axis=1))
                                    / self._abs_momentum0) if self._abs_momentum0 else 0.0,
            # correctly rounded (math.fsum): a BLAS dot's rounding depends on the arrays'
            # alignment in memory, so two runs of the same case could differ in the last bit
            "plastic_work": math.fsum(self.state.mass * self.state.plastic_work),
            "failure": record.failure,
            "probes": {name: {"index": i,
                              **self.problem.input_number(i),
                              "initial_position": self.state.initial_position[i].tolist()}
                       for name, i in self.problem.probes.items()},
        }


def _cpu_only(case: Case) -> str | None:
    """What in ``case`` runs on the CPU only, or None.  (Symmetry planes, axisymmetry's
    axis among them, run on the GPU since 2026-12-07: the whole step mirrors their ghosts'
    results there, the host path on the host.)"""
    if case.time.energy_update == "compatible" and not case.compute.resident:
        return ("time.energy_update = 'compatible' with compute.resident = false runs on the "
                "CPU only (the rates on the GPU with the state on the host have no work pass)")
    if case.kernel.max_stretch > 1.0 and not case.compute.resident:
        return ("kernel.max_stretch > 1 (a smoothing length set at each list build) with "
                "compute.resident = false runs on the CPU only")
    return None


#: the most particles of :func:`compile_case`'s copy of a case: twice the largest count at
#: which a pass changes its path (``passes.PREFETCH_ROWS``, the particle pass in the list's
#: order; 2D renumbering, from 500,000, is left to the runs)
COMPILE_PARTICLES = 32768


def compile_case(dim: int, like: Case | None = None) -> dict:
    """The small case whose one step :func:`compile_kernels` runs: blocks of 1 mm spacing
    moving at 1 m/s onto a wall.  Without ``like``: a 4 x 4 (x 4) elastic block with AC.
    With ``like``: a copy of that case, which compiles the passes generated for its options
    and its materials' models (each set of them is a module of its own,
    :mod:`impactsph.codegen`): every setting but the particles, the boundaries and the
    outputs is the case's (its plug-ins, 2D mode, formulation, materials, kernel, viscosity,
    stabilisation, contact, integrator and compute settings); each of its bodies becomes a
    block of its material and smoothing length, as many particles as it has up to a share of
    :data:`COMPILE_PARTICLES`, side by side along x, onto one wall (the case's first wall's
    slip and friction), beside a symmetry plane where the case has one.  Left to the runs:
    the code of tip masses, clamps, driven regions, probes and gauges."""
    axis = [0.0] * (dim - 1)
    wall = {"type": "wall", "point": [0.0] * dim, "normal": [*axis, 1.0]}
    if like is None:
        return {"name": f"compile_{dim}d", "dimension": dim,
                "materials": {"m": {"model": "elastic", "density": 1000.0,
                                    "youngs_modulus": 1e9}},
                "bodies": [{"name": "b", "material": "m", "velocity": [*axis, -1.0],
                            "geometry": {"origin": [0.0] * dim, "size": [4e-3] * dim,
                                         "spacing": 1e-3}}],
                "boundaries": [wall], "viscosity": {"scheme": "ac"},
                "time": {"end": 1.0, "max_steps": 1}, "output": {"figures": False}}
    case = like.model_dump(mode="json", exclude={"description"})
    case["name"] = f"compile_{dim}d_like_{like.name}"
    case["analysis"] = "none"
    counts = _counts(like)
    share = COMPILE_PARTICLES // len(like.bodies)
    bodies, start = [], 0.0
    for k, body in enumerate(like.bodies):
        # as many particles as the case's body up to a share of COMPILE_PARTICLES, at least
        # 4 a side: the passes' paths that depend on the count are the run's
        side = max(4, round(min(counts[k], share) ** (1.0 / dim)))
        bodies.append({"name": f"b{k}", "material": body.material,
                       "h_over_dx": body.h_over_dx, "velocity": [*axis, -1.0],
                       "geometry": {"origin": [start, *([0.0] * (dim - 1))],
                                    "size": [side * 1e-3] * dim, "spacing": 1e-3}})
        start += (side + 2) * 1e-3  # 2 mm apart: within reach, so contact is compiled too
    case["bodies"] = bodies
    walls = [b for b in case["boundaries"] if b.get("type", "wall") == "wall"]
    case["boundaries"] = [{**wall, **{k: v for k, v in walls[0].items()
                                      if k in ("slip", "friction")}} if walls else wall]
    if dim > 1 and any(b.type == "symmetry" for b in like.boundaries):
        # the blocks' side x = 0 on a symmetry plane: its images are compiled too
        case["boundaries"].append({"type": "symmetry", "point": [0.0] * dim,
                                   "normal": [1.0, *([0.0] * (dim - 1))]})
    case["time"] = {**case["time"], "end": 1.0, "max_steps": 1}
    case["output"] = {"figures": False,
                      "reference_viscosity": case["output"]["reference_viscosity"]}
    return case


def _counts(case: Case) -> list[int]:
    """The particles of each of the case's bodies (0 for a body whose particle file cannot be
    read: compiling ahead then takes the smallest copy)."""
    from .preflight import count_particles

    try:
        return count_particles(case)
    except (OSError, ValueError):
        return [0] * len(case.bodies)


def compile_key(case: Case) -> tuple:
    """What of ``case`` chooses the code its runs compile, so that a sweep calls
    :func:`compile_kernels` once for each (not for each value of a number that the compiled
    code only reads: a speed, a viscosity coefficient, a size): the dimension, formulation
    and plug-ins, the generated passes' options (:meth:`PassOptions.compiled`) of the run and
    of its reference run, the stage's (the materials' models), the viscosity schemes, the
    integrator, the stretch, the boundaries' kinds, several bodies or one, the device, and
    which side of the passes' size thresholds its particle count is on (what
    :func:`compile_case`'s copy compiles)."""
    from .physics import passes
    from .preflight import case_stage_options, reference_run
    from .solver import CHUNK

    reference = reference_run(case)
    schemes = [case.viscosity] + ([] if reference is None else [reference])
    n = sum(_counts(case))
    return (case.dimension, case.formulation, tuple(case.plugins),
            frozenset((v.scheme, PassOptions.of_case(case.model_copy(update={"viscosity": v}))
                       .compiled()) for v in schemes),
            case_stage_options(case),
            case.time.integrator, case.time.energy_update, case.kernel.max_stretch > 1.0,
            tuple(sorted({b.type for b in case.boundaries})), len(case.bodies) > 1,
            case.compute.device, case.compute.resident, n > CHUNK,
            n >= passes.PREFETCH_ROWS)


def compile_kernels(dim: int, like: Case | None = None) -> None:
    """Compile (or load from numba's disk cache) every kernel a run of dimension ``dim``
    needs, by running one step of :func:`compile_case`'s tiny case: a small copy of the case
    ``like`` if given (and of its reference run with ``output.reference_viscosity``, whose
    figures a run draws beside its own), else an elastic block with AC and a wall.  Processes
    starting on a cold cache at once would each compile the same code (numba's cache files
    are written under a lock, :func:`impactsph.jitcache.lock_cache_writes`): calling this
    first, in one process, compiles it once.  A copy of ``like`` that cannot be built or run
    (a setting that needs its own geometry, say) is logged and the elastic block is run
    instead: the runs then compile what it lacks themselves."""
    from .loading import validate_case
    from .preflight import reference_run

    cases = []
    if like is not None:
        copy = compile_case(dim, like)
        cases.append(copy)
        reference = reference_run(like)
        if reference is not None:
            cases.append({**copy, "name": copy["name"] + "_reference",
                          "viscosity": reference.model_dump(mode="json")})
    try:
        for case in cases:
            _compile_step(validate_case(case))
        if cases:
            return
    except Exception as exc:  # an optimisation: never the reason a sweep fails
        log.warning("compiling ahead for %r: its small copy did not run (%s); the runs "
                    "compile what the elastic block leaves out", like.name, exc)
    _compile_step(validate_case(compile_case(dim)))


def _compile_step(case: Case) -> None:
    """One step of ``case``, and the snapshots' pressures (what a run's kernels are)."""
    sim = Simulation(case)
    sim.run()
    sim.solver.pressure(sim.state)  # the snapshots' pressures
