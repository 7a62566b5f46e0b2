"""The total-Lagrangian solver: :class:`TotalLagrangianSolver`, the counterpart of
:class:`impactsph.solver.Solver` for ``formulation = "total_lagrangian"``
(:mod:`impactsph.physics.total_lagrangian`; docs/stabilisation.md, "Total-Lagrangian
formulation").

It returns the same ``(dv, drho, de, dS, dhg)`` as the updated-Lagrangian solver, so the
midpoint integrator and its compiled ``stage`` pass (the EOS, the strength model's return
map, the heating and the damage) are the same.  Bodies meet through a penalty contact
(:mod:`impactsph.physics.penalty_contact`), as LAMMPS SMD's total-Lagrangian bodies do, and a
rigid wall pushes a body as its mirror image would (:func:`~impactsph.physics.penalty_contact.
hertz_wall`), with the integrator's constraint behind it; there are no wall ghosts.  A body
does not fragment: its neighbours are those of t = 0 for the whole run.  CPU only.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from .boundaries import Walls
from .config import PENALTY_STIFFNESS
from .errors import CaseError
from .kernels import SUPPORT_RADIUS
from .materials import YOUNGS, carried_pressure
from .models.columns import DAMAGE
from .neighbours import NeighbourList
from .physics import total_lagrangian as tl
from .physics.penalty_contact import PenaltyContact, contact_diameters, hertz_wall, wall_frequency
from .physics.rates import RateBuffers, ViscositySettings, compiled_passes
from .state import ParticleState

#: the hourglass penalty's largest ``omega dt`` (:func:`hourglass_frequency`).  The penalty is
#: undamped, and the midpoint rule amplifies an undamped oscillation by ``1 + (omega dt)^4 / 8``
#: a step.  Measured on the 1D bars of Example 1 (total-Lagrangian, alpha = 10, AV (0.3, 0.3),
#: 20 us of a rod struck at 50 m/s): energy error 3.5e-4 at omega dt = 0.54, 1.0e-2 at 0.71,
#: and the run blows up at 1.07 (Courant 0.3 without this limit).
HOURGLASS_STEP = 0.5
#: with the penalty's dashpot (``stabilisation.tl_hourglass_damping`` zeta > 0) the step is
#: held to this fraction of the midpoint rule's stability limit for a mode of damping ratio
#: zeta (:func:`midpoint_stability_limit`: omega dt = 2.0 at zeta = 0.5, so 1.5, and the CFL
#: step at Courant 0.3, omega dt = 1.07-1.35 at alpha = 10, stands)
HOURGLASS_STEP_DAMPED = 0.75


def midpoint_stability_limit(zeta: float) -> float:
    """The largest ``omega dt`` for which the midpoint rule (two-stage Runge-Kutta, growth
    factor ``1 + z + z^2 / 2`` for ``z = lambda dt``) does not amplify a mode of frequency
    ``omega`` and damping ratio ``zeta`` (its eigenvalues ``lambda = omega (-zeta +- sqrt(zeta^2
    - 1))``); 0 for ``zeta = 0``, 2.0 at 0.5, 1.53 at 0.25, 1 / zeta for large zeta."""
    if zeta <= 0.0:
        return 0.0
    root = np.sqrt(complex(zeta * zeta - 1.0))
    roots = (-zeta + root, -zeta - root)

    def stable(w: float) -> bool:
        return all(abs(1 + z + z * z / 2) <= 1.0 + 1e-12 for z in (w * r for r in roots))

    low, high = 0.0, 1.0
    while stable(high):
        high *= 2.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stable(mid) else (low, mid)
    return low


def hourglass_frequency(ref: SimpleNamespace, m: np.ndarray, material: np.ndarray,
                        table: np.ndarray, alpha: float) -> np.ndarray:
    """Each particle's frequency (rad/s) in a zig-zag mode held by the hourglass penalty alone
    (:func:`impactsph.physics.total_lagrangian.hourglass_coefficient`: a spring ``k_ij = alpha E
    V0_i V0_j W_ij / |X_ij|^2`` per reference pair, ``E`` the pair's mean Young's modulus as
    there, ``W_ij / |X_ij|^2`` the reference list's ``w``, and a neighbour's displacement
    opposite to the particle's own doubling the stretch)::

        omega_i^2 = 2 sum_j k_ij / m_i

    The step is held to ``omega dt <= hourglass_step(zeta)`` (:class:`TotalLagrangianSolver`):
    without the dashpot that is 0.37-0.47 of the CFL step at Courant 0.3 with the default alpha
    = 10 (h = 1.2-1.3 dx, 1D to 3D); with the default zeta = 0.5 the CFL step stands."""
    n = m.shape[0]
    rows = np.repeat(np.arange(n), np.diff(ref.offsets))
    cols = ref.neighbours
    youngs = table[material, YOUNGS]
    k = alpha * 0.5 * (youngs[rows] + youngs[cols]) * ref.V0[rows] * ref.V0[cols] * ref.w
    return np.sqrt(2.0 * np.bincount(rows, weights=k, minlength=n) / m)


def hourglass_step(damping: float) -> float:
    """The largest ``omega dt`` allowed to the hourglass penalty of damping ratio ``damping``
    (:data:`HOURGLASS_STEP`, :data:`HOURGLASS_STEP_DAMPED`)."""
    if damping <= 0.0:
        return HOURGLASS_STEP
    return HOURGLASS_STEP_DAMPED * midpoint_stability_limit(damping)


def lattice_hourglass_step(dim: int, spacing: float, h: float, alpha: float, youngs: float,
                           density: float, damping: float = 0.0) -> float:
    """The hourglass penalty's step limit ``HOURGLASS_STEP / omega`` inside a full square
    (cubic) lattice of ``spacing`` (:func:`hourglass_frequency` summed over the lattice; the
    run's own limit is taken from its particles), for the pre-flight estimate."""
    from .kernels import cubic_spline

    reach = int(math.ceil(SUPPORT_RADIUS * h / spacing))
    grid = np.stack(np.meshgrid(*[np.arange(-reach, reach + 1)] * dim, indexing="ij"),
                    -1).reshape(-1, dim)
    r = np.linalg.norm(grid, axis=1) * spacing
    total = sum(spacing**dim * cubic_spline(float(d), h, dim) / d**2 for d in r if d > 0.0)
    omega = math.sqrt(2.0 * alpha * youngs / density * total)
    return hourglass_step(damping) / omega if omega > 0.0 else math.inf


#: the largest ``omega dt`` of a particle on the walls' push, ``omega^2 = (dF/dz) / m``
#: (:func:`~impactsph.physics.penalty_contact.hertz_wall`), at the start of each step: a
#: block of steel thrown at a wall at 100 m/s keeps its energy to 2.8e-3 at the CFL step
#: alone (omega dt about 0.3), 1.2e-3 with 0.2 and 8.1e-4 with 0.15 (docs/stabilisation.md,
#: "Total-Lagrangian formulation", Walls)
WALL_STEP = 0.15


#: the overlap with a wall, in contact diameters, beyond which a particle's start is
#: refused: (PC-4) would start it with an elastic energy it never had
START_OVERLAP = 0.01


def wall_start_overlap(x: np.ndarray, body: np.ndarray, diameter: np.ndarray,
                       points: np.ndarray, normals: np.ndarray) -> str | None:
    """The one-line refusal of a total-Lagrangian body whose surface starts inside a wall (a
    particle at ``x`` within half its contact ``diameter`` of a plane, less
    :data:`START_OVERLAP`), naming the wall (``boundaries.K``) and the particle; None if
    every body starts clear of the walls."""
    if x.shape[0] == 0:
        return None
    for k in range(points.shape[0]):
        z = (x - points[k]) @ normals[k]
        overlap = (diameter - 2.0 * z) / diameter
        worst = int(np.argmax(overlap))
        if overlap[worst] > START_OVERLAP:
            return (f"boundaries.{k}: particle {worst} of body {int(body[worst])} starts "
                    f"{z[worst]:.4g} m from the wall, its surface {overlap[worst]:.2f} of a "
                    f"contact diameter ({diameter[worst]:.4g} m) inside it; a "
                    f"total-Lagrangian body must start with its surface, half a contact "
                    f"diameter beyond its particles, clear of the wall")
    return None


class TotalLagrangianSolver:
    """Evaluates ``(dv/dt, drho/dt, de/dt, dS/dt, dhg/dt)`` (the last with no rows) for a
    state, on the reference configuration ``state.initial_position``.

    ``viscosity``: Monaghan's artificial viscosity (its ``pair`` parameters ``(alpha1, alpha2,
    epsilon, _)``); ``hourglass``: the coefficient alpha of the hourglass penalty
    (:func:`impactsph.physics.total_lagrangian.hourglass_coefficient`), 0 for none;
    ``penalty_stiffness`` and ``penalty_distance``: the contact between bodies
    (:class:`~impactsph.physics.penalty_contact.PenaltyContact`, used when there are two
    bodies or more) and with the rigid walls
    (:func:`~impactsph.physics.penalty_contact.hertz_wall`)."""

    def __init__(self, state: ParticleState, table: np.ndarray, viscosity: ViscositySettings,
                 walls: Walls | None = None, hourglass: float = 0.0,
                 penalty_stiffness: float = PENALTY_STIFFNESS, penalty_distance: float = 1.0,
                 hourglass_damping: float = 0.0):
        self.table = table
        self.viscosity = viscosity
        self.visc = np.array(viscosity.pair[:3], dtype=np.float64)
        self.hourglass = float(hourglass)
        self.walls = walls if walls is not None and len(walls) else None
        self.n_active = n = state.n
        self.dim = dim = state.dim
        self.backend = SimpleNamespace(device="cpu")
        self.pair_evaluations = 0
        self.rate_evaluations = 0
        self.powers = (0.0, 0.0, 0.0)
        self.wall_force = np.zeros(dim)
        several = np.unique(state.body).size > 1
        self.buffers = RateBuffers(n, dim, contact=several, corrected=False, hourglass=False)
        self._pressure = np.empty(n)
        self._damage = np.empty(n)
        self.F = np.zeros((n, dim, dim))
        self.Fdot = np.zeros((n, dim, dim))
        self._Q = np.zeros((n, dim, dim))
        self._pressures = compiled_passes(dim).pressures
        #: each particle's sound speed (the deformation pass's, for the force pass's viscosity)
        #: and Young's modulus (the hourglass penalty's)
        self._wave_speed = np.zeros(n)
        self._youngs = np.ascontiguousarray(table[state.material, YOUNGS], dtype=np.float64)
        X = np.ascontiguousarray(state.initial_position, dtype=np.float64)
        V0 = tl.reference_volumes(state.mass, state.material, table)
        self.ref = tl.reference(X, V0, state.smoothing_length, state.body)
        bad = np.flatnonzero(self.ref.det <= tl.SINGULAR_MOMENT ** dim)
        if bad.size:
            i = int(bad[0])
            raise CaseError(f"bodies: particle {i} at {X[i].tolist()} has too few reference "
                            f"neighbours for the total-Lagrangian gradient (det M = "
                            f"{self.ref.det[i]:.3g})")
        #: the reference neighbour list, as the checkpoints store a list (never rebuilt)
        self.neighbours = NeighbourList.build(X, SUPPORT_RADIUS * float(
            state.smoothing_length.max()), 0.0)
        self._ghost_src = np.zeros(0, dtype=np.int64)
        self._ghost_wall = np.zeros(0, dtype=np.int64)
        self._pairs = int(self.ref.neighbours.shape[0])
        #: the longest stable step (s) for the hourglass penalty (:func:`hourglass_frequency`)
        self.max_time_step = math.inf
        #: the hourglass penalty's dashpot time per particle, 2 zeta / omega_i (s)
        self._tau = np.zeros(n)
        if self.hourglass > 0.0 and n:
            omega = hourglass_frequency(self.ref, state.mass, state.material, table,
                                        self.hourglass)
            self.max_time_step = hourglass_step(hourglass_damping) / float(omega.max())
            if hourglass_damping > 0.0:
                self._tau = 2.0 * hourglass_damping / omega
        self._dashpot = bool(self._tau.any())
        #: m / (m + added mass), None without added mass (see :class:`~impactsph.solver.Solver`)
        self._inertia = state.inertia_fraction()
        #: the contact between bodies, None with one body
        self.contact = None
        if several:
            self.contact = PenaltyContact(state.mass, state.material, state.body, table, dim,
                                          scale=penalty_distance, stiffness=penalty_stiffness)
        self.penalty_stiffness = float(penalty_stiffness)
        if self.walls is not None:  # the walls' push (hertz_wall): each particle's diameter
            self._diameter = contact_diameters(state.mass, state.material, table, dim,
                                               penalty_distance)
            self._wall_push = np.zeros((n, dim))
            self._refuse_overlaps(state)

    def step_limit(self, state: ParticleState) -> float:
        """The longest stable step (s) at ``state``: the hourglass penalty's
        (:attr:`max_time_step`) and, with walls, :data:`WALL_STEP` over the largest frequency
        of a particle on the walls' push at ``state`` (a function of the state alone, so a
        run continued from a checkpoint takes the same steps)."""
        if self.walls is None:
            return self.max_time_step
        w = self.walls
        omega = wall_frequency(self.n_active, state.position, state.mass, state.material,
                               self.table, self._diameter, w.points, w.normals,
                               self.penalty_stiffness)
        return min(self.max_time_step, WALL_STEP / omega if omega > 0.0 else math.inf)

    def _refuse_overlaps(self, state: ParticleState) -> None:
        """Refuse, in one line, a body whose surface starts inside a wall
        (:func:`wall_start_overlap`, on the reference configuration: a run continued from a
        checkpoint may be on a wall)."""
        w = self.walls
        message = wall_start_overlap(state.initial_position, state.body, self._diameter,
                                     w.points, w.normals)
        if message is not None:
            raise CaseError(message)

    def restore(self, state: ParticleState, neighbours: NeighbourList, ghost_src: np.ndarray,
                ghost_wall: np.ndarray) -> None:
        """Restart from a checkpoint: nothing to take over (the reference configuration is
        ``state.initial_position``, set up already)."""

    def rates(self, state: ParticleState, time: float | None = None):
        """Rates at ``state``: ``(dv, drho, de, dS, dhg)``, ``dS`` the deviator's rate as its six
        components ``(n, 6)`` (as :meth:`impactsph.solver.Solver.rates`), ``dhg`` with no rows."""
        b, ref, n = self.buffers, self.ref, self.n_active
        self._pressures(state.density, state.specific_energy, state.material, self.table,
                        self._pressure)
        np.copyto(self._damage, state.material_state[:, DAMAGE])
        tl.deformation_pass(n, state.position, state.velocity, ref.V0, state.mass,
                            state.density, self._pressure, state.deviatoric_stress,
                            self._damage, state.material, self.table, ref.offsets,
                            ref.neighbours, ref.grad, ref.K, self.F, self.Fdot, self._Q,
                            b.drho, b.dS, b.de, self._wave_speed)
        tl.force_pass(n, state.position, state.velocity, ref.X, ref.V0, state.mass,
                      state.smoothing_length, state.density, self._wave_speed, self._youngs,
                      ref.offsets, ref.neighbours, ref.grad, ref.w, ref.dw, self.F, self._Q,
                      self.visc, self.hourglass, b.dv, b.de, b.de_visc, self.Fdot, self._tau,
                      self._dashpot)
        self.powers = (float(state.mass @ b.de_visc), 0.0, 0.0)
        if self.contact is not None:
            self.contact.add(n, state.position, state.velocity, state.mass, state.material,
                             b.dv, b.de, b.contact_force)
        if self.walls is not None:
            w = self.walls
            hertz_wall(n, state.position, state.velocity, state.mass, state.material,
                       self.table, self._diameter, w.points, w.normals, self.penalty_stiffness,
                       b.dv, b.de, self._wall_push)
            self.wall_force = self._wall_push.sum(axis=0)
        if self._inertia is not None:  # forces per own mass -> accelerations
            b.dv[:n] *= self._inertia[:, None]
        self.pair_evaluations += self._pairs
        self.rate_evaluations += 1
        return b.dv, b.drho, b.de, b.dS, b.dhg

    def pressure(self, state: ParticleState) -> np.ndarray:
        """Pressure (Pa) of each particle of ``state``, from the equations of state, a
        damaged particle's tension reduced by ``1 - D`` (as the forces see it)."""
        p = self._pressures(state.density, state.specific_energy, state.material, self.table,
                            np.empty(state.n))
        damage = state.material_state[:, DAMAGE]
        return carried_pressure(p, damage)
