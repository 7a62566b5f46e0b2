"""Problem set-up: from a validated :class:`~impactsph.config.Case` to particles and tables."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import Case, CaseError
from .driven import prescribed
from .geometry import body_particles, inside
from .initial import body_velocity
from .materials import MaterialModel, TableLayout, material_table, resolve_material
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


def build_problem(case: Case) -> Problem:
    """Place the particles of every body (:func:`~impactsph.geometry.body_particles`), set
    masses ``rho0 V`` from their volumes V (``dx^dim`` on a lattice; plus any tip mass),
    smoothing lengths ``h = (h/dx) dx``, initial velocities and clamped particles."""
    info: dict[str, float] = {}
    layout = TableLayout.registered()
    mat_names = list(case.materials)
    materials = [resolve_material(n, case.materials[n]) for n in mat_names]
    dim = case.dimension
    parts: dict[str, list[np.ndarray]] = {k: [] for k in
                                          ("x", "v", "rho", "m", "h", "body", "mat", "clamped",
                                           "temperature")}
    for b, body in enumerate(case.bodies):
        particles = body_particles(body.geometry, dim, where=f"bodies.{b}.geometry")
        x = particles.position
        k = mat_names.index(body.material)
        rho0 = materials[k].density
        n = x.shape[0]
        mass = rho0 * particles.volume
        velocity = body_velocity(body.velocity, x)
        if particles.velocity is not None:  # a particle file's velocity columns
            velocity += particles.velocity
        clamped = np.zeros(n, dtype=bool)
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
            mass[sel] += extra / sel.sum()
            velocity[sel] = np.asarray(tip.velocity) * extra / (extra + own)
            info["tip_initial_speed"] = float(np.linalg.norm(tip.velocity) * extra
                                              / (extra + own))
        parts["x"].append(x)
        parts["v"].append(velocity)
        parts["rho"].append(np.full(n, rho0))
        parts["m"].append(mass)
        # anisotropic lattices: the spacing is the geometric mean of the axes' spacings
        parts["h"].append(np.full(n, case.kernel.h_over_dx * particles.spacing))
        parts["body"].append(np.full(n, b, dtype=np.int32))
        parts["mat"].append(np.full(n, k, dtype=np.int32))
        parts["clamped"].append(clamped)
        parts["temperature"].append(particles.temperature if particles.temperature is not None
                                    else np.full(n, np.nan))
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    n = cat["x"].shape[0]
    state = ParticleState(
        position=np.ascontiguousarray(cat["x"]), velocity=np.ascontiguousarray(cat["v"]),
        density=cat["rho"], specific_energy=np.zeros(n), deviatoric_stress=np.zeros((n, 3, 3)),
        mass=cat["m"], smoothing_length=cat["h"], body=cat["body"], material=cat["mat"],
        clamped=cat["clamped"], material_state=np.zeros((n, layout.state_width)),
    )
    initialise_material_state(state, materials, layout)
    from_file = np.isfinite(cat["temperature"])  # a particle file's temperature column
    state.material_state[from_file, TEMPERATURE] = cat["temperature"][from_file]
    body_names = [b.name for b in case.bodies]
    probes = {p.name: nearest_particle(state, body_names.index(p.body), p.position)
              for p in case.output.probes}
    gauges = {g.name: nearest_particle(state, body_names.index(g.body), g.position)
              for g in case.output.gauges}
    return Problem(state, materials, material_table(materials, case.time.wave_speed, layout),
                   body_names, probes, info, gauges)
