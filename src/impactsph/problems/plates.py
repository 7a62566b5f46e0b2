"""Symmetric plate impact in uniaxial strain: the elastic precursor and the plastic wave
against their exact jump conditions (``analysis = "plates"``; the built-in case ``plates``).

Two identical plates (1D, uniaxial strain: the deviator keeps ``S_yy = S_zz = -S_xx / 2``)
of an elastic-perfectly plastic von Mises material with the linear equation of state meet at
``+-V``.  With the compressive log strain ``lambda = ln(rho / rho0)`` the stress along the
loading path of the run's own constitutive law (the Jaumann rate integrates ``S_xx = -(4/3)
G lambda`` in 1D, the yield is ``2 G lambda = Y``) is, compression positive::

    sigma(lambda) = K (exp(lambda) - 1) + (4/3) G min(lambda, Y / (2 G))

Both branches stiffen, so each loading wave is a shock.  In Lagrangian form, with the strain
``eps = 1 - rho0 / rho = 1 - exp(-lambda)``, a shock of speed ``U`` (per unit initial length)
carries ``[u] = U [eps]`` and ``[sigma] = rho0 U [u]``.  The precursor takes the material from
rest at ``u = V`` (centre-of-mass frame) to the yield point, ``lambda_1 = Y / (2 G)``::

    U_1 = sqrt(sigma_1 / (rho0 eps_1)),   u_1 = V - U_1 eps_1

and the plastic shock takes it to rest (``u_2 = 0``, by symmetry): ``sigma_2 - sigma_1 =
rho0 u_1^2 / (eps_2 - eps_1)``, solved for ``lambda_2`` (the left side rises with it, the
right falls), ``U_2 = u_1 / (eps_2 - eps_1)``.  Below the yield (``V <= U_1 eps_1``) a
single elastic shock brings the material to rest.  For a particle of the left plate at
initial coordinate ``X`` (in ``[-L, 0]``), before the precursor reaches the free end
(``t < L / U_1``)::

    X < -U_1 t: u = V;    -U_1 t < X < -U_2 t: u = u_1;    X > -U_2 t: u = 0

The measures, on the latest snapshot before ``L / U_1``: the velocity profile's relative L1
error and its excess total variation (as for the bars), the plateau velocity between the two
fronts against ``u_1``, and the speeds of the two fronts (each where a step with the same
momentum between its two states would be) against ``U_1`` and ``U_2``.

Found with it (docs/dissipation.md): at ``h = 1.2 dx`` in 1D the kernel gradient's first
moment on a lattice, ``-sum_j dx x_ij dW/dx_ij``, is 1.022, not 1, so the plain scheme's
strain rate and forces are both 2.2% large and every wave runs 2.2% fast, at any spacing; the
correction of the velocity gradient and forces (``stabilisation.gradient_correction``)
removes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .base import GeometryNeeds, ProblemKind


@dataclass(frozen=True)
class PlateTheory:
    """The exact two-wave solution for the left plate (see the module docstring)."""

    length: float  #: m, the left plate's length L
    speed: float  #: m/s, V, each plate's speed in the centre-of-mass frame
    frame_velocity: float  #: m/s, the centre of mass's velocity
    precursor_speed: float  #: m/s, U_1 (Lagrangian)
    plateau_velocity: float  #: m/s, u_1 (centre-of-mass frame)
    plastic_speed: float  #: m/s, U_2 (Lagrangian; 0 when the impact is elastic)
    stresses: tuple[float, float]  #: Pa, (sigma_1, sigma_2), compression positive

    @property
    def elastic(self) -> bool:
        """Whether the impact stays below the yield (a single wave)."""
        return self.plastic_speed == 0.0

    def velocity(self, X: np.ndarray, t: float) -> np.ndarray:
        """Velocity of left-plate points at initial coordinates ``X`` (lab frame)."""
        X = np.asarray(X, np.float64)
        if self.elastic:
            u = np.where(X < -self.precursor_speed * t, self.speed, 0.0)
        else:
            u = np.where(X < -self.precursor_speed * t, self.speed,
                         np.where(X < -self.plastic_speed * t, self.plateau_velocity, 0.0))
        return self.frame_velocity + u


def plate_theory(rho0: float, bulk: float, shear: float, yield_stress: float, speed: float,
                 length: float, frame_velocity: float = 0.0) -> PlateTheory:
    """The jump conditions of the module docstring for one material and impact speed."""
    from scipy.optimize import brentq

    def sigma(lam: float) -> float:
        return bulk * math.expm1(lam) + 4.0 / 3.0 * shear * min(lam, lam_y)

    def strain(lam: float) -> float:
        return -math.expm1(-lam)

    lam_y = yield_stress / (2.0 * shear)
    s1, e1 = sigma(lam_y), strain(lam_y)
    U1 = math.sqrt(s1 / (rho0 * e1))
    u1 = speed - U1 * e1
    if u1 <= 0.0:  # elastic: one shock from (0, 0, V) to rest
        lam = brentq(lambda x: sigma(x) * strain(x) - rho0 * speed**2, 1e-300, lam_y)
        U = speed / strain(lam)
        return PlateTheory(length, speed, frame_velocity, U, 0.0, 0.0, (sigma(lam), sigma(lam)))
    lam2 = brentq(lambda x: (sigma(x) - s1) * (strain(x) - e1) - rho0 * u1**2, lam_y,
                  lam_y + 2.0)
    U2 = u1 / (strain(lam2) - e1)
    return PlateTheory(length, speed, frame_velocity, U1, u1, U2, (s1, sigma(lam2)))


def theory_for(case: Any) -> PlateTheory:
    """The theory of a plates case: its first body's material and length, half the approach
    speed, the centre of mass's velocity."""
    left, right = case.bodies[0], case.bodies[1]
    mat = case.materials[left.material]
    if mat.model != "elastic_plastic" or mat.eos != "linear":
        raise ValueError(f"materials.{left.material}: the plates' theory is for model = "
                         f"'elastic_plastic' with eos = 'linear' (got {mat.model!r}, "
                         f"{mat.eos!r})")
    E, nu = mat.youngs_modulus, mat.poisson_ratio
    shear = mat.shear_modulus if mat.shear_modulus is not None else E / (2 * (1 + nu))
    return plate_theory(mat.density, E / (3 * (1 - 2 * nu)), shear, mat.yield_stress,
                        0.5 * (left.velocity[0] - right.velocity[0]), left.geometry.size[0],
                        0.5 * (left.velocity[0] + right.velocity[0]))


def profile_measures(X: np.ndarray, v: np.ndarray, theory: PlateTheory, t: float,
                     smoothing_length: float) -> dict[str, float]:
    """The measures of the module docstring from the left plate's profile at time ``t``
    (particles at initial coordinates ``X`` on a uniform lattice).  Each front's position is
    that of the step with the same momentum between its two states: ``X_1 = -L + sum dX (u -
    u_1)^+ / (V - u_1)`` over the plate, ``X_2 = -L + sum dX min(u, u_1) / u_1`` (a front
    smeared by the viscosity, symmetrically or not, keeps its place)."""
    order = np.argsort(X)
    X, u = X[order], v[order] - theory.frame_velocity
    dX = float(np.median(np.diff(X)))
    L, V, u1 = theory.length, theory.speed, theory.plateau_velocity
    ut = theory.velocity(X, t) - theory.frame_velocity
    rel = ut - V  # the change from the state ahead
    out = {"velocity_profile_l1_error": float(np.sum(np.abs(u - ut)) / np.sum(np.abs(rel))),
           "velocity_profile_oscillation": float((np.sum(np.abs(np.diff(u)))
                                                  - np.sum(np.abs(np.diff(ut)))) / V),
           "precursor_speed_theory": theory.precursor_speed}
    if theory.elastic:
        x1 = -L + dX * float(np.sum(np.clip(u, 0.0, None))) / V
        out["precursor_speed_error"] = -x1 / t / theory.precursor_speed - 1.0
        return out
    x1 = -L + dX * float(np.sum(np.clip(u - u1, 0.0, None))) / (V - u1)
    x2 = -L + dX * float(np.sum(np.clip(u, 0.0, u1))) / u1
    out.update({"plastic_speed_theory": theory.plastic_speed, "plateau_velocity_theory": u1,
                "precursor_speed_error": -x1 / t / theory.precursor_speed - 1.0,
                "plastic_speed_error": -x2 / t / theory.plastic_speed - 1.0})
    margin = 3.0 * smoothing_length
    plateau = (X > x1 + margin) & (X < x2 - margin)
    if plateau.sum() >= 3:
        out["plateau_velocity_error"] = float((np.mean(u[plateau]) - u1) / V)
    return out


class PlatesProblem(ProblemKind):
    """Symmetric plate impact in uniaxial strain (``analysis = "plates"``) against the exact
    elastic precursor and plastic shock."""

    name = "plates"
    title = "plate impact in uniaxial strain: elastic precursor and plastic wave, exact"
    geometry_needs = GeometryNeeds(bodies=2, types=("block",))
    animation_field = "velocity_x"
    # the profiles are measured while the waves run (Example 2 ends at 1.2 us, a third of the
    # kinetic energy left): no warning that the impact may not be over
    ends_during_impact = True

    def metrics(self, sim: Any) -> dict[str, Any]:
        """The measures of the module docstring (a note where one cannot be taken)."""
        from ..measures import attempt

        notes: list[str] = []
        out: dict[str, Any] = {}
        theory = attempt(notes, "plates theory", lambda: theory_for(sim.case))
        if theory is None:
            return {"notes": notes}
        limit = theory.length / theory.precursor_speed
        snaps = [s for s in sim.record.snapshots if 0.0 < s.time < limit]
        if not snaps:
            notes.append(f"velocity_profile_l1_error: not measured, no snapshot between 0 and "
                         f"{limit * 1e6:.4g} us (when the precursor reaches the free end; "
                         "output.snapshot_times)")
        else:
            snap = snaps[-1]
            left = np.flatnonzero(snap.fields["body"] == 0)

            def measure() -> dict[str, float]:
                return {"profile_time_us": snap.time * 1e6,
                        **profile_measures(sim.state.initial_position[left, 0],
                                           snap.fields["velocity"][left, 0], theory,
                                           snap.time,
                                           float(sim.h_reference[left].max()))}

            out.update(attempt(notes, "velocity profile", measure, {}))
        if notes:
            out["notes"] = notes
        return out

    def summary_keys(self, case: Any) -> tuple[str, ...]:
        """Profile error and oscillation, the plateau and the two fronts."""
        return ("velocity_profile_l1_error", "velocity_profile_oscillation",
                "plateau_velocity_error", "precursor_speed_error", "plastic_speed_error")

    def table_keys(self, case: Any) -> tuple[str, ...]:
        """As :meth:`summary_keys`."""
        return self.summary_keys(case)

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """``velocity_profile.png``: the left plate's profile against the exact one."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from ..loading import validate_case

        drawn = False
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        theory = None
        t = 0.0
        for run, label in zip(runs, labels, strict=False):
            theory = theory_for(validate_case(run["case"]))
            limit = theory.length / theory.precursor_speed
            snaps = [snap for snap in run.get("snapshots", []) if 0.0 < snap["time"] < limit]
            if not snaps:
                continue
            snap = snaps[-1]
            left = snap["body"] == 0
            X = snap["initial_position"][left, 0]
            order = np.argsort(X)
            ax.plot(X[order] * 1e3, snap["velocity"][left, 0][order], lw=1.2, label=label)
            t = float(snap["time"])
            drawn = True
        if not drawn or theory is None:
            plt.close(fig)
            return []
        Xs = np.linspace(-theory.length, 0.0, 2001)
        ax.plot(Xs * 1e3, theory.velocity(Xs, t), "k--", lw=1.0, label="exact")
        ax.set_xlabel("initial position X (mm)")
        ax.set_ylabel("velocity (m/s)")
        ax.set_title(f"left plate at t = {t * 1e6:.3g} us")
        ax.legend(fontsize=8)
        path = Path(out) / "velocity_profile.png"
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        return [path]
