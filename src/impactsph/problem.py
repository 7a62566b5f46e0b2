"""Problem set-up: from a validated :class:`~impactsph.config.Case` to particles and tables."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import Case, CaseError
from .driven import prescribed
from .geometry import body_particles, inside
from .initial import body_velocity
from .materials import MaterialModel, TableLayout, case_materials, material_table
from .models import DAMAGE
from .models.columns import TEMPERATURE, THICKNESS_RATIO
from .state import ParticleState


@dataclass
class Problem:
    """Everything a solver needs, built from a case."""

    state: ParticleState
    materials: list[MaterialModel]
    table: np.ndarray
    body_names: list[str]
    probes: dict[str, int]
    info: dict[str, float] = field(default_factory=dict)  #: set-up facts worth reporting
    #: ``output.gauges``: name -> the particle followed (chosen as the probes are)
    gauges: dict[str, int] = field(default_factory=dict)
    #: in a renumbered run (``compute.particle_order``, :func:`particle_order`): each
    #: particle's number as the bodies placed it (``input_index[i]``: the row of particle
    #: ``i`` in the bodies' particles, body after body, each in its geometry's order); None:
    #: the particles are numbered so
    input_index: np.ndarray | None = None

    def input_number(self, i: int) -> dict[str, int]:
        """``{"input_index": n}``, particle ``i``'s number as placed, for a summary's entry
        of a renumbered run; empty where the particles are numbered as placed."""
        return {} if self.input_index is None else {"input_index": int(self.input_index[i])}


def nearest_particle(state: ParticleState, body: int, position: list[float]) -> int:
    """The particle of body ``body`` nearest to ``position`` (a probe's or a gauge's)."""
    members = np.flatnonzero(state.body == body)
    d = np.linalg.norm(state.position[members] - np.asarray(position), axis=1)
    return int(members[np.argmin(d)])


def initialise_material_state(state: ParticleState, materials: list[MaterialModel],
                              layout: TableLayout) -> None:
    """The material state at t = 0: each particle's temperature its material's initial one,
    and the damage model's own state (``DamageModel.initial_state``, e.g. the Grady-Kipp
    flaws) body by body, from the particles' volumes ``m / rho0`` and a generator seeded by
    the damage parameters' ``seed`` (0 if none) and the body's index; the thickness ratio 1."""
    state.material_state[:, THICKNESS_RATIO] = 1.0
    for k, material in enumerate(materials):
        sel = state.material == k
        state.material_state[sel, TEMPERATURE] = material.temperature
        model = DAMAGE[material.damage]
        if model.initial_state is None:
            continue
        width = len(model.state)
        for b in np.unique(state.body[sel]):
            members = np.flatnonzero(sel & (state.body == b))
            seed = int(getattr(material.damage_parameters, "seed", 0))
            rng = np.random.default_rng([seed, int(b)])
            own = model.initial_state(material.damage_parameters,
                                      state.mass[members] / material.density, rng)
            state.material_state[members, layout.damage_state: layout.damage_state + width] = own


def stressed_state(stress: np.ndarray, k: int, table: np.ndarray, dim: int,
                   two_dimensional: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The density and deviator of particles of material ``k`` that start with the Cauchy
    stress ``stress`` (n, 3, 3): ``S = sigma + P I`` with ``P = -tr(sigma)/3``, and the
    density at which the material's equation of state gives ``P`` (at zero specific energy,
    the state every particle starts in), found by Newton's method on the compiled EOS from
    ``rho0 (1 + P / K)``, to ``|P(rho) - P| <= 1e-10 (|P| + 1 Pa)``.  A pressure no density
    gives, or a plane-stress ``sigma_zz`` other than 0, is a :class:`CaseError` naming
    ``where`` and the particle."""
    from .materials import BULK, RHO0
    from .physics.rates import pressures

    if two_dimensional == "plane_stress":
        bad = np.flatnonzero(stress[:, 2, 2] != 0.0)
        if bad.size:
            raise CaseError(f"{where}: particle {int(bad[0])} has sigma_zz = "
                            f"{float(stress[bad[0], 2, 2])!r}; in plane stress it is 0")
    n = stress.shape[0]
    target = -np.trace(stress, axis1=1, axis2=2) / 3.0
    deviator = stress + target[:, None, None] * np.eye(3)
    material = np.full(n, k, dtype=np.int32)
    energy = np.zeros(n)
    rho0, bulk = table[k, RHO0], table[k, BULK]
    rho = rho0 * np.maximum(1.0 + target / bulk, 0.05)

    def residual(r: np.ndarray) -> np.ndarray:
        return pressures(r, energy, material, table, dim, np.empty(n)) - target

    tolerance = 1e-10 * (np.abs(target) + 1.0)
    for _ in range(60):
        f = residual(rho)
        if (np.abs(f) <= tolerance).all():
            break
        step = 1e-7 * rho
        slope = (residual(rho + step) - f) / step
        slope = np.where(slope > 0.0, slope, bulk / rho)  # the EOS stiffens with density
        rho = np.clip(rho - f / slope, 0.5 * rho, 2.0 * rho)
    bad = np.flatnonzero(~(np.abs(residual(rho)) <= tolerance))
    if bad.size:
        i = int(bad[0])
        raise CaseError(f"{where}: particle {i}'s pressure {float(target[i]):.6g} Pa is one "
                        f"the material's equation of state gives at no density (nearest "
                        f"{float(target[i] + residual(rho)[i]):.6g} Pa)")
    return rho, deviator


def axisymmetric_masses(state: ParticleState, body_names: list[str]) -> None:
    """Axisymmetry: each particle is a ring about the y axis at the radius ``r = x``; its mass
    is per radian, ``rho r V``, and ``density`` is the mass per radian and unit area of the
    r-z plane, ``rho r``, the thickness column holding ``r`` (docs/modelling.md).  A particle
    at ``x <= 0`` is a :class:`CaseError`."""
    r = state.position[:, 0]
    bad = np.flatnonzero(~(r > 0.0))
    if bad.size:
        i = int(bad[0])
        raise CaseError(f"bodies.{int(state.body[i])}: a particle of body "
                        f"{body_names[int(state.body[i])]!r} is at x = {float(r[i])!r}; with "
                        f"two_dimensional = 'axisymmetric' x is the radius, > 0")
    state.mass *= r
    state.added_mass *= r  # a tip mass is spread as the particles' own masses are
    state.density *= r
    state.material_state[:, THICKNESS_RATIO] = r


def build_problem(case: Case) -> Problem:
    """Place the particles of every body (:func:`~impactsph.geometry.body_particles`), set
    masses ``rho0 V`` from their volumes V (``dx^dim`` on a lattice), a tip mass as added
    inertia (or, ``carried_as = "particle_mass"``, in the masses),
    smoothing lengths ``h = (h/dx) dx``, initial velocities and clamped particles."""
    info: dict[str, float] = {}
    layout = TableLayout.registered()
    mat_names = list(case.materials)
    materials = case_materials(case)
    dim = case.dimension
    table = material_table(materials, case.time.wave_speed, layout)
    parts: dict[str, list[np.ndarray]] = {k: [] for k in
                                          ("x", "v", "rho", "m", "h", "body", "mat", "clamped",
                                           "added", "temperature", "S")}
    for b, body in enumerate(case.bodies):
        particles = body_particles(body.geometry, dim, where=f"bodies.{b}.geometry")
        x = particles.position
        k = mat_names.index(body.material)
        rho0 = materials[k].density
        n = x.shape[0]
        density = np.full(n, rho0)
        deviator = np.zeros((n, 3, 3))
        if particles.stress is not None:  # a particle file's initial stress
            density, deviator = stressed_state(
                particles.stress, k, table, dim, case.two_dimensional,
                f"bodies.{b}.geometry.path = {str(body.geometry.path)!r}")
        mass = density * particles.volume
        velocity = body_velocity(body.velocity, x)
        if particles.velocity is not None:  # a particle file's velocity columns
            velocity += particles.velocity
        clamped = np.zeros(n, dtype=bool)
        added = np.zeros(n)
        clamps = body.clamped if isinstance(body.clamped, list) else [body.clamped]
        for region in clamps:
            if region is not None:
                held = inside(x, region.origin, region.size)
                clamped |= held
                velocity[held] = 0.0
        for k, drive in enumerate(body.driven):  # held as clamped, moved at v_p(t)
            sel = inside(x, drive.origin, drive.size)
            if not sel.any():
                raise CaseError(f"bodies.{b}.driven.{k} holds no particle of body "
                                f"{body.name!r}")
            clamped |= sel
            velocity[sel] = prescribed(drive.velocity, 0.0)
        if body.tip_mass is not None:
            tip = body.tip_mass
            sel = inside(x, tip.region.origin, tip.region.size)
            if not sel.any():
                raise CaseError(f"bodies.{b}.tip_mass.region holds no particle of body "
                                f"{body.name!r}")
            extra = tip.mass / (tip.depth if dim == 2 else 1.0)
            own = float(mass[sel].sum())
            if tip.carried_as == "particle_mass":  # the paper's: heavier, larger particles
                mass[sel] += extra / sel.sum()
            else:  # a rigid mass moving with the particles: inertia, not volume
                added[sel] += extra / sel.sum()
            velocity[sel] = np.asarray(tip.velocity) * extra / (extra + own)
            info["tip_initial_speed"] = float(np.linalg.norm(tip.velocity) * extra
                                              / (extra + own))
        parts["x"].append(x)
        parts["v"].append(velocity)
        parts["rho"].append(density)
        parts["S"].append(deviator)
        parts["m"].append(mass)
        # anisotropic lattices: the spacing is the geometric mean of the axes' spacings
        parts["h"].append(np.full(n, case.h_over_dx_of(b) * particles.spacing))
        parts["body"].append(np.full(n, b, dtype=np.int32))
        parts["mat"].append(np.full(n, k, dtype=np.int32))
        parts["clamped"].append(clamped)
        parts["added"].append(added)
        parts["temperature"].append(particles.temperature if particles.temperature is not None
                                    else np.full(n, np.nan))
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    n = cat["x"].shape[0]
    state = ParticleState(
        position=np.ascontiguousarray(cat["x"]), velocity=np.ascontiguousarray(cat["v"]),
        density=cat["rho"], specific_energy=np.zeros(n), deviatoric_stress=cat["S"],
        mass=cat["m"], smoothing_length=cat["h"], body=cat["body"], material=cat["mat"],
        clamped=cat["clamped"],
        material_state=np.zeros((n, layout.state_width_of_table(table))),
        added_mass=cat["added"],
    )
    initialise_material_state(state, materials, layout)
    body_names = [b.name for b in case.bodies]
    if case.two_dimensional == "axisymmetric":
        axisymmetric_masses(state, body_names)
    from_file = np.isfinite(cat["temperature"])  # a particle file's temperature column
    state.material_state[from_file, TEMPERATURE] = cat["temperature"][from_file]
    probes = {p.name: nearest_particle(state, body_names.index(p.body), p.position)
              for p in case.output.probes}
    gauges = {g.name: nearest_particle(state, body_names.index(g.body), g.position)
              for g in case.output.gauges}
    input_index = None
    if particle_order(case, n) == "cells":
        # the probes and gauges chosen in the input order (a tie goes to the same particle
        # whatever the order), then followed to their new numbers
        input_index = cell_numbering(state, case.time.neighbour_skin)
        renumber(state, input_index)
        number_of = np.empty_like(input_index)
        number_of[input_index] = np.arange(n)
        probes = {name: int(number_of[i]) for name, i in probes.items()}
        gauges = {name: int(number_of[i]) for name, i in gauges.items()}
    return Problem(state, materials, table,
                   body_names, probes, info, gauges, input_index)


#: particles from which ``compute.particle_order = "auto"`` renumbers a 2D run's particles
#: (benchmarks/README.md, "The particles in the list's order": the 2D Taylor bar's step took
#: 0.80-0.81 of its time at 1e6 particles, 0.90-0.91 at 5.1e5 and 1.01-1.05 at 1.1e5; the 3D
#: Taylor cylinder's 1.00 at 1e6)
RENUMBER_FROM = 500_000


def renumbering_pays(case: Case, n: int) -> bool:
    """Whether a run of ``case`` with ``n`` particles is one where renumbering was measured
    to pay: 2D, updated Lagrangian, :data:`RENUMBER_FROM` particles or more."""
    return (case.dimension == 2 and n >= RENUMBER_FROM
            and case.formulation == "updated_lagrangian")


def particle_order(case: Case, n: int) -> str:
    """``compute.particle_order`` resolved for a run of ``n`` particles: ``"auto"`` is
    ``"cells"`` where :func:`renumbering_pays`, else ``"input"``."""
    order = case.compute.particle_order
    if order != "auto":
        return order
    return "cells" if renumbering_pays(case, n) else "input"


def cell_numbering(state: ParticleState, skin_fraction: float) -> np.ndarray:
    """A renumbered run's numbering (``compute.particle_order``): the particles in the order
    the run's first neighbour list numbers them (:func:`impactsph.neighbours.cell_order`, its
    cells of edge ``2 h_max (1 + skin_fraction)`` in Z order, a cell's particles in their
    input order), body by body (each body's particles stay together, in the bodies' order).
    Returns the input number of the particle at each new place.  Without walls and with one
    body, the first list's order is then the identity: the passes read and write the rows by
    particle number in the order they walk the list, and each particle's rates are those of
    the input order's run to the bit (``tests/test_particle_order.py``)."""
    from .kernels import SUPPORT_RADIUS
    from .neighbours import cell_order

    if state.n == 0:
        return np.zeros(0, dtype=np.int64)
    radius = SUPPORT_RADIUS * float(state.smoothing_length.max()) * (1.0 + skin_fraction)
    order = np.asarray(cell_order(state.position, radius), dtype=np.int64)
    return order[np.argsort(state.body[order], kind="stable")]


def renumber(state: ParticleState, order: np.ndarray) -> None:
    """Every per-particle array of ``state`` taken in ``order`` (the new particle ``i`` is
    the old ``order[i]``), in place."""
    for name, values in state.arrays().items():
        if values.ndim >= 1 and values.shape[0] == state.n:
            setattr(state, name, np.ascontiguousarray(values[order]))
