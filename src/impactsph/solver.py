"""The solver: neighbour list, wall ghosts, rate passes and viscosity scheme composed into one
``rates`` function for the integrator.  It takes plain data (arrays, the material table, a
:class:`~impactsph.physics.rates.ViscositySettings`), never the case's pydantic models."""

from __future__ import annotations

import numba as nb
import numpy as np

from .boundaries import (
    SYMMETRY,
    Walls,
    fill_ghosts,
    friction_push,
    layer_push,
    mirror_ghost_matrices,
    mirror_ghost_results,
)
from .kernels import SUPPORT_RADIUS
from .materials import carried_pressure
from .models.columns import (
    CARRIED,
    DAMAGE,
    PASS_CARRIED,
    VISCOSITY_FACTOR,
    VISCOSITY_MEMORY,
)
from .neighbours import NeighbourList
from .physics.rates import CpuRates, RateBuffers, ViscositySettings, pressures
from .physics.stretch import stretched_smoothing_length
from .state import ParticleState

#: Particles per work item of :func:`rate_totals`' partial sums.
CHUNK = 2048


@nb.njit(inline="always", cache=True)
def _chunk_totals(chunk, n, m, de_visc, books, contact_force, pair_count, corrected, part):
    """:func:`rate_totals`' partial sums of one chunk of particles into ``part[chunk]``."""
    dim = contact_force.shape[1]
    heat = work = corr_heat = pairs = 0.0
    # the force's components in scalars, not a small array: an array's sums went through
    # memory, a load and a store per particle and component (the same sums, the same order)
    f0 = f1 = f2 = 0.0
    for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n)):
        heat += m[i] * de_visc[i]
        pairs += pair_count[i]
        if contact_force.shape[0] > 0:
            f0 += contact_force[i, 0]
            if dim > 1:
                f1 += contact_force[i, 1]
            if dim > 2:
                f2 += contact_force[i, 2]
        if corrected:
            work += m[i] * books[i, 0]
            corr_heat += m[i] * books[i, 1]
    part[chunk, 0] = heat
    part[chunk, 1] = work
    part[chunk, 2] = corr_heat
    part[chunk, 3] = pairs
    part[chunk, 4] = f0
    part[chunk, 5] = f1
    part[chunk, 6] = f2


@nb.njit(inline="always", cache=True)
def _added_parts(part):
    totals = np.zeros(7)
    for chunk in range(part.shape[0]):
        for k in range(7):
            totals[k] += part[chunk, k]
    return totals


@nb.njit(parallel=True, cache=True)
def rate_totals(n, m, de_visc, books, contact_force, pair_count, corrected):
    """Sums over the first ``n`` particles: ``sum m de_visc`` (W), the correction's power
    ``sum m books[:, 0]`` (W: ``sum m v . a_c`` of the acceleration ``a_c`` it adds) and
    heating ``sum m books[:, 1]`` (W), ``sum contact_force`` (N or N/m) and the pair count.
    Partial sums per chunk, added in a fixed order (independent of the number of threads)."""
    part = np.zeros((max(1, (n + CHUNK - 1) // CHUNK), 7))
    for chunk in nb.prange(part.shape[0]):
        _chunk_totals(chunk, n, m, de_visc, books, contact_force, pair_count, corrected, part)
    return _added_parts(part)


@nb.njit(cache=True)
def value_range(values):  # pragma: no cover (compiled)
    """``(smallest, largest)`` of the 1D array ``values`` in one pass: the smoothing lengths'
    at every rate evaluation (the support from the largest; whether they are all the same):
    0.8-0.95 us on the cantilever's 1,020 against 4.2-5.2 us for the three reductions
    (``h.max()`` here, ``h.min()`` and ``h.max()`` in the backend) it replaces.  Four running
    pairs over interleaved values, not one: one pair is a chain of compares that waits on
    itself (2026-12-07: 32 us against 98 us for the 2D lattice's 1e5 values, 0.6 us against
    1.4 us for 1,020; the same values: a minimum and a maximum are exact in any order)."""
    n = values.shape[0]
    if n == 0:
        raise ValueError("value_range of an empty array")
    least0 = least1 = least2 = least3 = most0 = most1 = most2 = most3 = values[0]
    k = 1
    while k + 4 <= n:
        v0, v1, v2, v3 = values[k], values[k + 1], values[k + 2], values[k + 3]
        least0, least1 = min(least0, v0), min(least1, v1)
        least2, least3 = min(least2, v2), min(least3, v3)
        most0, most1 = max(most0, v0), max(most1, v1)
        most2, most3 = max(most2, v2), max(most3, v3)
        k += 4
    while k < n:
        least0, most0 = min(least0, values[k]), max(most0, values[k])
        k += 1
    return (min(min(least0, least1), min(least2, least3)),
            max(max(most0, most1), max(most2, most3)))


@nb.njit(cache=True)
def serial_rate_totals(n, m, de_visc, books, contact_force, pair_count, corrected):
    """:func:`rate_totals` without threads, the same sums in the same order: for a run of
    one chunk, where starting a parallel region costs more than it gives.  (A function of
    its own: numba's cache would give a second compilation of the same Python function the
    first one's code.)"""
    part = np.zeros((max(1, (n + CHUNK - 1) // CHUNK), 7))
    for chunk in range(part.shape[0]):
        _chunk_totals(chunk, n, m, de_visc, books, contact_force, pair_count, corrected, part)
    return _added_parts(part)


class Solver:
    """Evaluates ``(dv/dt, drho/dt, de/dt, dS/dt)`` for a state.

    The state's particles are integrated; rigid walls add ghost particles that only take part
    in sums.  The rates returned have one row per particle, ghosts after the real ones.  The
    neighbour list carries a skin of ``skin_fraction`` times the kernel support and is
    rebuilt (with a new set of ghosts) when a particle has moved by half the skin.
    ``backend`` runs the rate passes: :class:`~impactsph.physics.rates.CpuRates` (default)
    or :class:`impactsph.gpu.GpuRates`.  ``hourglass``: the hourglass control's zeta;
    ``wall_layer``: the thickness (in particle spacings) of the walls' penalty layer
    (:func:`impactsph.boundaries.layer_push`), 0 for none.  ``max_stretch`` > 1: at each list
    build after the first, each particle's smoothing length becomes ``h_reference`` (its
    smoothing length at t = 0; the state's own at the first build if not given) times its
    neighbourhood's largest principal stretch, clamped to ``[1, max_stretch]``
    (:mod:`impactsph.physics.stretch`).
    """

    def step_limit(self, state: ParticleState) -> float:
        """The solver's own limit on the step at ``state`` (s): none beyond eq 26 (the
        total-Lagrangian solver has one)."""
        return float("inf")

    def __init__(self, state: ParticleState, table: np.ndarray, viscosity: ViscositySettings,
                 walls: Walls | None = None, skin_fraction: float = 0.1, backend=None,
                 hourglass: float = 0.0, wall_layer: float = 0.0, max_stretch: float = 1.0,
                 h_reference: np.ndarray | None = None):
        self.table = table
        self.max_stretch = float(max_stretch)
        self._h_reference = None  # read only with the stretch
        if self.max_stretch > 1.0:
            self._h_reference = (np.asarray(h_reference, dtype=float)
                                 if h_reference is not None
                                 else state.smoothing_length.copy())
        self.wall_layer = float(wall_layer)
        self.hourglass = float(hourglass)
        self.viscosity = viscosity
        self.walls = walls if walls is not None and len(walls) else None
        self.n_active = state.n
        self.dim = state.dim
        self.n_bodies = int(state.body.max()) + 1 if state.n else 1
        self.backend = backend if backend is not None else CpuRates(state.dim)
        self.skin_fraction = skin_fraction
        self.pair_evaluations = 0
        self.rate_evaluations = 0
        self.corrected = viscosity.correction is not None
        self.switched = viscosity.switch is not None
        self.powers = (0.0, 0.0, 0.0)
        self.wall_force = np.zeros(state.dim)
        self.neighbours: NeighbourList | None = None
        #: with ghosts, the state whose fields are views of the extended arrays' first rows,
        #: and those views by field name (:meth:`_allocate`)
        self._bound: ParticleState | None = None
        self._views: dict[str, np.ndarray] = {}
        #: the passes' copy of the common material state and the switch's columns, without
        #: ghosts for a scheme with a switch (or a material state not C-contiguous float64);
        #: otherwise the passes read the material state itself (with ghosts: ``_ext``)
        self._carried: np.ndarray | None = None
        #: symmetry planes: their ghosts get the mirror of their sources' pair results
        self._symmetric = self.walls is not None and bool((self.walls.kinds == SYMMETRY).any())
        self._friction = self.walls is not None and bool((self.walls.friction > 0.0).any())
        options = getattr(self.backend, "options", None)
        self._axisymmetric = bool(getattr(options, "axisymmetric", False))
        #: the compatible energy update (:meth:`work_rates`)
        self.compatible = bool(getattr(options, "compatible_energy", False))
        self._scratch: RateBuffers | None = None  # the work pass's discarded results
        self._positions: np.ndarray | None = None  # row -> place in the packed records
        rigid = np.zeros(0, dtype=np.int64) if self.walls is None else self.walls.walls_only
        self._rigid = rigid
        if self.walls is not None:  # the rigid walls' planes, for the penalty layer
            self._rigid_points = np.ascontiguousarray(self.walls.points[rigid])
            self._rigid_normals = np.ascontiguousarray(self.walls.normals[rigid])
        #: m / (m + added mass) of each particle, None without added mass: the forces per own
        #: mass the passes return become accelerations (a tip mass carried as inertia)
        self._inertia = state.inertia_fraction()
        self._build(state)

    def _build(self, state: ParticleState) -> None:
        """Choose the ghosts, size the arrays and build the neighbour list (with
        ``max_stretch`` > 1, after setting the smoothing lengths from the old list)."""
        if self.max_stretch > 1.0 and self.neighbours is not None:
            w = self.walls
            ghosts = None if w is None else (self._ghost_src, self._ghost_wall, w.points,
                                             w.normals, w.kinds)
            state.smoothing_length[:] = stretched_smoothing_length(
                self.neighbours, state.position, state.initial_position, state.body,
                self._h_reference, self.max_stretch, state.smoothing_length, ghosts)
        support = SUPPORT_RADIUS * float(state.smoothing_length.max())
        skin = self.skin_fraction * support
        if self.walls is not None:
            src, wall = self.walls.select(state.position, support + skin)
        else:
            src = wall = np.zeros(0, dtype=np.int64)
        positions = self._allocate(state, src, wall)
        old = self.neighbours
        builds = old.builds if old is not None else 0
        # the old list's offsets size the new one's room (its build's single sweep); its
        # indices are freed first: the peak memory is one list (and that room)
        like = None if old is None else old.offsets
        self.neighbours = old = None
        # an inner list for the CPU's correction and switch passes (the GPU's kernels read the
        # whole list)
        reach = (self.viscosity.inner_reach
                 if getattr(self.backend, "device", "cpu") == "cpu" else 1.0)
        # where the smoothing lengths differ (the stretch, a width per body) a radius per pair
        # keeps each row to its own pairs' reach, not the largest h's (neighbours.py)
        h = state.smoothing_length
        varied = self.max_stretch > 1.0 or (h.shape[0] > 0 and h.max() > h.min())
        h_rows = self._row_smoothing_lengths(state) if varied else None
        self.neighbours = NeighbourList.build(positions, support, skin, reach, h_rows,
                                              like)
        self.neighbours.builds += builds
        self._positions = None

    def _row_smoothing_lengths(self, state: ParticleState) -> np.ndarray:
        """Each row of the list's h: the particles', then the ghosts' (their sources', set by
        :meth:`_allocate`'s fill)."""
        return state.smoothing_length if self._ext is None else self._ext["h"]

    def restore(self, state: ParticleState, neighbours: NeighbourList, ghost_src: np.ndarray,
                ghost_wall: np.ndarray) -> None:
        """Take over a stored neighbour list and set of ghosts (restart from a checkpoint)."""
        self._allocate(state, ghost_src.astype(np.int64), ghost_wall.astype(np.int64))
        self.neighbours = neighbours
        self._positions = None  # the records' places follow this list's order, as after a build

    def _allocate(self, state: ParticleState, ghost_src: np.ndarray, ghost_wall: np.ndarray
                  ) -> np.ndarray:
        """Arrays for the real particles and the given ghosts; returns all positions."""
        n = state.n
        self._ghost_src, self._ghost_wall = ghost_src, ghost_wall
        n_ext = n + ghost_src.shape[0]
        if self.walls is not None:
            # without a switch the passes read the common columns of the material state
            # only, so its rows can be the carried array's (below)
            width = PASS_CARRIED if self.switched else state.material_state.shape[1]
            ext = {"x": np.zeros((n_ext, self.dim)), "v": np.zeros((n_ext, self.dim)),
                   "rho": np.zeros(n_ext), "e": np.zeros(n_ext), "S": np.zeros((n_ext, 3, 3)),
                   "carried": np.zeros((n_ext, width)), "m": np.zeros(n_ext),
                   "h": np.zeros(n_ext),
                   "material": np.zeros(n_ext, np.int32), "body": np.zeros(n_ext, np.int32)}
            ext["m"][:n], ext["h"][:n] = state.mass, state.smoothing_length
            ext["material"][:n], ext["body"][:n] = state.material, state.body
            # the state's integrated fields become views of the extended arrays' first n
            # rows: the integrator writes where the passes read, and _fill copies nothing
            # of them (the integrator and the rest write these fields in place).  The solver
            # is bound to this state: another one handed to rates() is bound in its turn
            # (_fill), so that neither's values are written into the other's arrays
            views = {}
            for key, name in self._aliased():
                field = getattr(state, name)
                if field.dtype == ext[key].dtype and field.shape[1:] == ext[key].shape[1:]:
                    ext[key][:n] = field
                    views[name] = ext[key][:n]
                    setattr(state, name, views[name])
            self._bound, self._views = state, views
            self._ext = ext
            self._fill(state)
            positions = ext["x"]
        else:
            self._ext = None
            positions = state.position
        if self.neighbours is None or self.buffers.drho.shape[0] != n_ext:
            self.buffers = RateBuffers(n_ext, self.dim,
                                       contact=self.walls is not None or self.n_bodies > 1,
                                       corrected=self.corrected,
                                       hourglass=self.hourglass > 0.0,
                                       switched=self.switched,
                                       compatible=self.compatible)
        return positions

    def _aliased(self) -> tuple[tuple[str, str], ...]:
        """The extended arrays whose first rows are the state's fields (key, field name):
        the material state only without a switch, whose factor and memory take its
        columns after the common ones."""
        fields = (("x", "position"), ("v", "velocity"), ("rho", "density"),
                  ("e", "specific_energy"), ("S", "deviatoric_stress"))
        return fields if self.switched else (*fields, ("carried", "material_state"))

    def _fill(self, state: ParticleState) -> None:
        """Copy the real particles into the extended arrays (the fields that are not views
        of them already: :meth:`_allocate`) and mirror them into ghosts.  A state other than
        the one the arrays were made for is bound to new arrays first."""
        if state is not self._bound:
            self._allocate(state, self._ghost_src, self._ghost_wall)  # calls _fill again
            return
        ext, n = self._ext, state.n
        for key, name in self._aliased():
            field = getattr(state, name)
            if field is not self._views.get(name):  # a field handed an array of its own
                if key == "carried":
                    ext[key][:n, :CARRIED] = field[:, :CARRIED]
                else:
                    ext[key][:n] = field
        if self.switched:  # read only by the passes of a scheme with a switch
            ext["carried"][:n, :CARRIED] = state.material_state[:, :CARRIED]
            ext["carried"][:n, VISCOSITY_FACTOR] = state.viscosity_factor
            ext["carried"][:n, VISCOSITY_MEMORY] = state.viscosity_memory
        w = self.walls
        fill_ghosts(self._ghost_src, self._ghost_wall, w.points, w.normals, w.kinds, n,
                    ext["x"], ext["v"], ext["rho"], ext["e"], ext["S"], ext["carried"], ext["m"],
                    ext["h"], ext["material"], ext["body"], self.n_bodies)

    def _record_positions(self) -> np.ndarray:
        """Each row's place in the packed records (the inverse of the list's order)."""
        order = self.neighbours.order
        if self._positions is None or self._positions.shape[0] != order.shape[0]:
            self._positions = np.empty(order.shape[0], dtype=np.int64)
            self._positions[order] = np.arange(order.shape[0])
        return self._positions

    def _mirror(self, packed: np.ndarray, gradients: np.ndarray, u_column: int) -> None:
        """:func:`impactsph.boundaries.mirror_ghost_results` for this list's order."""
        w = self.walls
        mirror_ghost_results(self._ghost_src, self._ghost_wall, w.normals, w.kinds,
                             self.n_active, self._record_positions(), packed, u_column,
                             self.dim, gradients)

    def _mirror_moments(self, packed: np.ndarray, c0: int) -> None:
        """:func:`impactsph.boundaries.mirror_ghost_matrices` for this list's order."""
        w = self.walls
        mirror_ghost_matrices(self._ghost_src, self._ghost_wall, w.normals, w.kinds,
                              self.n_active, self._record_positions(), packed, c0, self.dim)

    def _arrays(self, state: ParticleState):
        """``(x, v, rho, e, S, m, h, material, body, carried)`` of every row, ghosts
        included (``carried``: the common material state, :mod:`impactsph.models.columns`)."""
        if self._ext is None:
            carried = state.material_state
            if (self.switched or not carried.flags.c_contiguous
                    or carried.dtype != np.float64):
                # the passes' own copy: the common columns, then the switch's two
                if self._carried is None or self._carried.shape[0] != state.n:
                    self._carried = np.zeros((state.n, PASS_CARRIED))
                np.copyto(self._carried[:, :CARRIED], carried[:, :CARRIED])
                if self.switched:
                    self._carried[:, VISCOSITY_FACTOR] = state.viscosity_factor
                    self._carried[:, VISCOSITY_MEMORY] = state.viscosity_memory
                carried = self._carried
            # else the material state itself: its first CARRIED columns are the common ones,
            # and only a scheme with a switch reads the columns after them
            return (state.position, state.velocity, state.density, state.specific_energy,
                    state.deviatoric_stress, state.mass, state.smoothing_length, state.material,
                    state.body, carried)
        self._fill(state)
        e = self._ext
        return (e["x"], e["v"], e["rho"], e["e"], e["S"], e["m"], e["h"], e["material"],
                e["body"], e["carried"])

    def rates(self, state: ParticleState, time: float | None = None):
        """Rates at ``state`` (Table 1's subroutine RATES): ``(dv, drho, de, dS, dhg)``, ``dS``
        the deviator's rate as its six components ``(xx, xy, xz, yy, yz, zz)``
        (:func:`impactsph.physics.stress_rate.symmetric_full` gives the 3x3 tensors), ``dhg``
        with no rows unless the hourglass control is on; rows beyond ``state.n`` are
        ghosts.  ``time``: the time of the evaluated state (the integrator's stages; a
        viscosity switch sets the factors for that time, None: set them without time passing).
        """
        b = self.buffers
        h_least, h_most = value_range(state.smoothing_length)
        support = SUPPORT_RADIUS * h_most
        if self.neighbours.stale(state.position, support):
            self._build(state)
            b = self.buffers
        extra = ({"after_pairs": self._mirror, "after_moments": self._mirror_moments}
                 if self._symmetric else {})
        extra["n_bodies"] = self.n_bodies  # rows of a larger body index are walls' ghosts
        # whether the rows' h are all the same (CpuRates.neighbour_loops; the ghosts' are
        # their sources'), except with the stretch, whose h start equal and part at a later
        # build: one compiled module a run, not two
        extra["uniform_h"] = bool(h_least == h_most) if self.max_stretch <= 1.0 else False
        if self.switched:
            extra["switch_elapsed"] = (0.0 if time is None
                                       else max(time - state.viscosity_factor_time, 0.0))
        if self.hourglass > 0.0:
            self.backend.evaluate(self.n_active, self._arrays(state), self.table,
                                  self.neighbours, self.viscosity, b, self.hourglass,
                                  state.hourglass_acceleration, **extra)
        else:
            self.backend.evaluate(self.n_active, self._arrays(state), self.table,
                                  self.neighbours, self.viscosity, b, **extra)
        n = self.n_active
        if self.switched:  # the factors for the next evaluation (a half step later)
            state.viscosity_factor[:] = b.factor[:n]
            state.viscosity_memory[:] = b.memory[:n]
            if time is not None:
                state.viscosity_factor_time = time
        # (one chunk: the same sums without a parallel region, whose start costs more)
        totals = (rate_totals if n > CHUNK else serial_rate_totals)(
            n, state.mass, b.de_visc, b.correction_books, b.contact_force, b.pair_count,
            self.corrected)
        # powers at the evaluated state (W): the artificial viscosity's heating, the work rate
        # of the AC correction force on the particles and the correction's heating; after a
        # step, those of its midpoint evaluation
        self.powers = (float(totals[0]), float(totals[1]), float(totals[2]))
        if self.walls is not None:  # the ghosts' push on the real particles (N, or N/m)
            self.wall_force = totals[4: 4 + self.dim].copy()
            if self._friction:  # Coulomb friction of the walls, from the ghosts' push
                w = self.walls
                self.wall_force += friction_push(
                    n, state.position, state.velocity, state.mass, state.material, self.table,
                    b.contact_force, w.points, w.normals, w.friction, support, b.dv, b.de)
            if self.wall_layer > 0.0 and self._rigid.size:  # rigid walls, not symmetry planes
                self.wall_force += layer_push(n, state.position, state.velocity, state.mass,
                                              state.material, self.table, self._rigid_points,
                                              self._rigid_normals, self.wall_layer, b.dv, b.de,
                                              self._axisymmetric)
        if self._inertia is not None:  # forces per own mass -> accelerations
            b.dv[:n] *= self._inertia[:, None]
        self.pair_evaluations += int(totals[3])
        self.rate_evaluations += 1
        return b.dv, b.drho, b.de, b.dS, b.dhg

    def work_rates(self, state: ParticleState, mean_velocity: np.ndarray
                   ) -> tuple[np.ndarray, float]:
        """The compatible energy update's correction to the last evaluation's specific-energy
        rates (W/kg, one per particle): the pair pass's energy terms again, with the forces of
        that evaluation (its records, neighbours and ghosts) and the velocity differences of
        ``mean_velocity`` (the step's mean velocity of each particle, ``(v(t) + v(t + dt))
        / 2``; the ghosts get their sources' mirrored as their velocities are), less what
        that evaluation's energy terms gave.  Added to ``de`` over the step it makes the
        internal energy the pair forces' work at the step's mean velocity, so that kinetic
        plus internal energy is kept exactly by those forces (Owen 2014, Int. J. Numer. Meth.
        Fluids 75:749; docs/modelling.md, "The compatible energy update").  The other
        passes' energy terms (hourglass control, friction, the walls' penalty layer, a
        correction) keep their evaluation's rates.  Returns the correction and the work
        pass's viscous heating (W)."""
        n = self.n_active
        b = self.buffers
        if self._ext is None:
            work = mean_velocity
        else:
            ext = self._ext
            work = np.empty_like(ext["v"])
            work[:n] = mean_velocity
            w = self.walls  # the ghosts' rows from their sources, as in the evaluation
            fill_ghosts(self._ghost_src, self._ghost_wall, w.points, w.normals, w.kinds, n,
                        ext["x"], work, ext["rho"], ext["e"], ext["S"], ext["carried"],
                        ext["m"], ext["h"], ext["material"], ext["body"], self.n_bodies)
        rows = work.shape[0]
        if self._scratch is None or self._scratch.de.shape[0] != rows:
            self._scratch = RateBuffers(rows, self.dim, contact=False, corrected=False)
        S = state.deviatoric_stress if self._ext is None else self._ext["S"]
        material = state.material if self._ext is None else self._ext["material"]
        de = self.backend.work_energy(n, work, self.neighbours, self.viscosity, S, material,
                                      self.table, self._scratch)
        self.pair_evaluations += int(self._scratch.pair_count[:n].sum())
        return de[:n] - b.de_pairs[:n], float(state.mass @ self._scratch.de_visc[:n])

    def pressure(self, state: ParticleState) -> np.ndarray:
        """Pressure (Pa) of each particle of ``state``, from the equations of state, a
        damaged particle's tension reduced by ``1 - D`` (as the forces see it)."""
        p = pressures(state.material_density, state.specific_energy, state.material, self.table,
                      self.dim, np.empty(state.n))
        damage = state.material_state[:, DAMAGE]
        return carried_pressure(p, damage)
