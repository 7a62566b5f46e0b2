"""The material-point driver: one material point taken through a homogeneous deformation by
the same compiled functions a run uses (the EOS, the Jaumann rate, the strength model's return
map, the heating, the damage model), with no SPH around it.

It is how a material is checked against its formulas (``tests/test_strength.py``) and how a
user looks at a material before a run: the flow stress of a Johnson-Cook copper at 1e3/s, the
strain at which a steel fails in tension, the time a brittle bar takes to break::

    from impactsph.material_point import material_point
    history = material_point(case.materials["copper"], mode="uniaxial_stress",
                             strain_rate=1e3, strain=0.5)
    history.axial_stress, history.equivalent_plastic_strain, history.temperature

Deformations (the axial direction is x; ``strain_rate`` is the axial true strain rate, > 0 in
tension):

- ``uniaxial_strain``: ``L = diag(rate, 0, 0)`` (a plate impact's state);
- ``uniaxial_stress``: ``L = diag(rate, l, l)`` with the lateral rate ``l`` found each step
  (by the secant method, to ``|sigma_yy| <= 1e-9 |sigma_xx|``) so that the lateral stress
  is zero (a tensile or compression test);
- ``shear``: simple shear, ``L_xy = rate`` (the rotation of the stress by the Jaumann rate
  included).

With ``plane_stress=True`` the point is a particle of a 2D plane-stress run: the driver gives
the in-plane velocity gradient (``L_zz`` of the modes above dropped) and the run's stage finds
the thickness strain rate that keeps ``sigma_zz = 0``
(:func:`impactsph.physics.passes.plane_stress_stage`); ``uniaxial_stress`` is then a tensile
test of a thin sheet, and ``thickness_ratio`` records ``t / t0``.

Each step is one forward-Euler stage of the run's integrator stage
(:func:`impactsph.physics.passes.advance_particle`), with the density rate ``-rho tr D`` and
the internal energy rate ``sigma : D / rho`` of the damaged stress.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from .integrate import run_stage
from .materials import (
    MaterialModel,
    TableLayout,
    carried_pressure,
    material_table,
    resolve_material,
)
from .models import DAMAGE
from .models.columns import (
    DAMAGE as DAMAGE_COLUMN,
)
from .models.columns import (
    EQUIVALENT_PLASTIC_STRAIN,
    PLASTIC_STRAIN_RATE,
    TEMPERATURE,
    THICKNESS_RATIO,
)
from .physics.options import PassOptions
from .physics.rates import compiled_passes
from .physics.stress_rate import jaumann_stress_rate, symmetric_upper
from .physics.survey import SURVEY_WIDTH

Mode = Literal["uniaxial_strain", "uniaxial_stress", "shear"]


@dataclass
class MaterialPointHistory:
    """The state of the point after each step (index 0: the start), SI units."""

    time: np.ndarray  #: s
    #: the true (logarithmic) strain along x; the shear strain gamma for ``shear``
    axial_strain: np.ndarray
    stress: np.ndarray  #: (n, 3, 3) Cauchy stress ``-P I + (1 - D) S`` (tension positive), Pa
    pressure: np.ndarray  #: the (damaged) pressure, Pa
    von_mises_stress: np.ndarray  #: of the damaged deviator, Pa
    equivalent_plastic_strain: np.ndarray
    plastic_strain_rate: np.ndarray  #: 1/s
    temperature: np.ndarray  #: K
    damage: np.ndarray
    plastic_work: np.ndarray  #: J/kg
    density: np.ndarray  #: the material's density, kg/m^3
    own_state: np.ndarray  #: (n, k): the strength and damage models' own state columns
    thickness_ratio: np.ndarray  #: t / t0 (plane stress; 1 otherwise)

    @property
    def axial_stress(self) -> np.ndarray:
        """``sigma_xx`` (Pa, tension positive)."""
        return self.stress[:, 0, 0]

    @property
    def shear_stress(self) -> np.ndarray:
        """``sigma_xy`` (Pa)."""
        return self.stress[:, 0, 1]


def _resolved(material: Any, name: str) -> MaterialModel:
    if isinstance(material, MaterialModel):
        return material
    if isinstance(material, dict):
        from .config import schema
        material = schema().Material.model_validate(material)
    return resolve_material(name, material)


def material_point(material: Any, *, strain_rate: float, strain: float | None = None,
                   duration: float | None = None, mode: Mode = "uniaxial_stress",
                   steps: int = 2000, flaws: np.ndarray | None = None,
                   size: float = 1e-3, plane_stress: bool = False) -> MaterialPointHistory:
    """Drive one point of ``material`` (a validated case material, its dict, or a
    :class:`MaterialModel`) at the axial true strain rate ``strain_rate`` (1/s) to the true
    strain ``strain`` or for ``duration`` s, in ``steps`` equal steps.  ``flaws``: the
    damage model's own state at the start (e.g. Grady-Kipp's ``(N, eps_min, eps_max)``;
    default: its ``initial_state`` for one particle of volume ``size^3``); ``size``: the
    particle's smoothing length h (m), which sets the Grady-Kipp growth time;
    ``plane_stress``: a particle of a 2D plane-stress run (see the module's docstring)."""
    if (strain is None) == (duration is None):
        raise ValueError("give exactly one of strain and duration")
    if strain_rate == 0.0:
        raise ValueError("strain_rate = 0.0: the point would not move; give a non-zero rate")
    if duration is None:
        duration = abs(float(strain) / strain_rate)
    if steps < 1:
        raise ValueError(f"steps = {steps}: at least 1")
    model = _resolved(material, "material")
    layout = TableLayout.registered()
    table = material_table([model], "longitudinal", layout)
    dim = 2 if plane_stress else 3
    k = compiled_passes(dim, options=PassOptions(plane_stress=plane_stress))
    dt = duration / steps
    n = steps + 1

    def one(a):
        return np.zeros((1,) + a)

    x0, v0, x, v = one((3,)), one((3,)), one((3,)), one((3,))
    rho0, e0, pw0 = np.full(1, model.density), np.zeros(1), np.zeros(1)
    rho, e, pw = rho0.copy(), e0.copy(), pw0.copy()
    # the deviator at the step's start and now (3x3); the advance's start copy and rate: six
    # components (stress_rate.UPPER)
    S0, S, S0_six, dS = one((3, 3)), one((3, 3)), one((6,)), one((6,))
    state0 = np.zeros((1, layout.state_width))
    state0[0, TEMPERATURE] = model.temperature
    state0[0, THICKNESS_RATIO] = 1.0
    damage_model = DAMAGE[model.damage]
    width = len(damage_model.state)
    if flaws is not None:
        state0[0, layout.damage_state: layout.damage_state + width] = flaws
    elif damage_model.initial_state is not None:
        rng = np.random.default_rng([int(getattr(model.damage_parameters, "seed", 0)), 0])
        state0[0, layout.damage_state: layout.damage_state + width] = \
            damage_model.initial_state(model.damage_parameters, np.array([size ** 3]), rng)[0]
    state = state0.copy()
    hg0, hg, dhg = np.zeros((1, 0)), np.zeros((1, 0)), np.zeros((1, 0))
    dv, drho, de = one((3,)), np.zeros(1), np.zeros(1)
    clamped, mat, h = np.zeros(1, bool), np.zeros(1, np.int32), np.full(1, size)

    out = {name: np.zeros(n) for name in ("pressure", "von_mises", "eps", "rate", "T", "D",
                                          "work", "rho", "tau")}
    stresses = np.zeros((n, 3, 3))
    own = np.zeros((n, layout.state_width - layout.strength_state))

    def pressure_of(rho_, e_, damage):
        return float(carried_pressure(k.pressures(rho_, e_, mat, table, np.empty(1)),
                                      damage)[0])

    def record(step):
        D = state0[0, DAMAGE_COLUMN]
        tau = state0[0, THICKNESS_RATIO]
        p = pressure_of(rho0 / tau, e0, D)
        sigma = (1.0 - D) * S0[0] - p * np.eye(3)
        stresses[step] = sigma
        out["pressure"][step] = p
        dev = (1.0 - D) * S0[0]
        out["von_mises"][step] = math.sqrt(1.5 * float(np.sum(dev * dev)))
        out["eps"][step] = state0[0, EQUIVALENT_PLASTIC_STRAIN]
        out["rate"][step] = state0[0, PLASTIC_STRAIN_RATE]
        out["T"][step] = state0[0, TEMPERATURE]
        out["D"][step] = D
        out["work"][step] = pw0[0]
        out["rho"][step] = rho0[0] / tau
        out["tau"][step] = tau
        own[step] = state0[0, layout.strength_state:]

    # the integrator's stage without walls or a survey (its arrays for those, unused)
    no_walls = (np.zeros((0, 3)), np.zeros((0, 3)), np.ones(1), np.zeros((2, 4)))
    no_survey = (np.ones(1), 0.0, np.zeros((2, SURVEY_WIDTH)), np.zeros(2, dtype=np.int64))

    def stage(L):
        """One forward-Euler step from the start arrays with velocity gradient L."""
        L = np.ascontiguousarray(L[:dim, :dim])
        D = 0.5 * (L + L.T)
        damage = state0[0, DAMAGE_COLUMN]
        tau = state0[0, THICKNESS_RATIO]
        p = pressure_of(rho0 / tau, e0, damage)
        sigma = (1.0 - damage) * S0[0] - p * np.eye(3)
        drho[0] = -rho0[0] * np.trace(D)  # in plane stress: the mass per area over t0
        de[0] = tau * float(np.sum(sigma[:dim, :dim] * D)) / rho0[0]
        jaumann_stress_rate(L, S0[0], model.shear_modulus, dS[0])
        S0_six[:] = symmetric_upper(S0)
        run_stage(k.stage, False, 1, dt, False, x0, v0, rho0, e0, S0_six, pw0, state0, hg0, v0,
                  dv, drho, de, dS, dhg, clamped, mat, table, h, x, v, rho, e, S, pw, state, hg,
                  *no_walls, False, *no_survey)
        p_new = pressure_of(rho / state[0, THICKNESS_RATIO], e, state[0, DAMAGE_COLUMN])
        return (1.0 - state[0, DAMAGE_COLUMN]) * S[0] - p_new * np.eye(3)

    record(0)
    lateral = 0.0
    for step in range(1, n):
        if mode == "uniaxial_strain":
            stage(np.diag([strain_rate, 0.0, 0.0]))
        elif mode == "shear":
            L = np.zeros((3, 3))
            L[0, 1] = strain_rate
            stage(L)
        elif mode == "uniaxial_stress":
            def lateral_stress(rate_l):
                return stage(np.diag([strain_rate, rate_l, rate_l]))[1, 1]
            a, fa = lateral, lateral_stress(lateral)
            scale = max(abs(stage(np.diag([strain_rate, a, a]))[0, 0]), 1.0)
            b = lateral - 0.5 * strain_rate if lateral == 0.0 else 1.01 * lateral
            fb = lateral_stress(b)
            for _ in range(60):
                if abs(fb) <= 1e-9 * scale or fb == fa:
                    break
                a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
                fb = lateral_stress(b)
            lateral = b
            stage(np.diag([strain_rate, lateral, lateral]))
        else:
            raise ValueError(f"mode = {mode!r}: one of uniaxial_strain, uniaxial_stress, "
                             f"shear")
        rho0[:], e0[:], S0[:], pw0[:], state0[:] = rho, e, S, pw, state
        record(step)
    time = np.arange(n) * dt
    return MaterialPointHistory(
        time=time, axial_strain=strain_rate * time, stress=stresses,
        pressure=out["pressure"], von_mises_stress=out["von_mises"],
        equivalent_plastic_strain=out["eps"], plastic_strain_rate=out["rate"],
        temperature=out["T"], damage=out["D"], plastic_work=out["work"], density=out["rho"],
        own_state=own, thickness_ratio=out["tau"])
