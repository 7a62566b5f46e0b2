"""The clamped elastic beam of issue 11: the period of its first bending mode against beam
theory, at several resolutions and for each stabilisation option.

A plane-strain steel beam (E = 200 GPa, nu = 0.3, rho = 7800 kg/m^3), H = 10 mm deep and
L = 12 H long, clamped at x = 0 (three columns of particles behind the root held at rest),
starts in the first mode shape of a cantilever with a tip speed of 0.5 m/s (an elastic
motion: peak strain about 1e-4).  The period is twice the time between the first two zero
crossings of the mean tip deflection, against

- Euler-Bernoulli: ``omega = (beta L)^2 sqrt(E' I / (rho A L^4))``, ``beta L = 1.8751``,
  ``E' = E / (1 - nu^2)`` (plane strain);
- Timoshenko (shear and rotary inertia, Cowper's shear coefficient ``10 (1 + nu) / (12 +
  11 nu)``), from a converged finite-element model of 400 two-node Timoshenko elements
  (reduced integration of the shear term), the reference of the issue's bound.

Usage::

    .venv/bin/python validation/beam.py 5 10 20                # the case's defaults
    .venv/bin/python validation/beam.py 5 10 \
        --set stabilisation.gradient_correction=none --set stabilisation.hourglass=0  # plain
    .venv/bin/python validation/beam.py 5 10 \
        --set stabilisation.gradient_correction=velocity_gradient --set stabilisation.hourglass=1
    .venv/bin/python validation/beam.py 5 10 20 --formulation total_lagrangian

The defaults of an elastic case (``stabilisation`` ``"auto"``) are the kernel gradient
correction and the hourglass control (docs/stabilisation.md), not plain SPH. Each line printed
is one run (JSON): particles through the depth, period, its error against Timoshenko and
Euler-Bernoulli, energy error, steps and wall time, and the stabilisation that ran.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np
from _args import positive_int

E, RHO, NU = 200e9, 7800.0, 0.3
DEPTH = 0.01  # m
LENGTH = 12 * DEPTH  # m
BETA_L = 1.8751040687119611  # first root of cos(x) cosh(x) = -1
TIP_SPEED = 0.5  # m/s
ROOT_COLUMNS = 3


def plane_strain_modulus() -> float:
    """``E' = E / (1 - nu^2)``: the bending modulus of a plane-strain beam."""
    return E / (1.0 - NU**2)


def euler_bernoulli_period() -> float:
    """First-mode period of the clamped-free Euler-Bernoulli beam (s)."""
    omega = BETA_L**2 * math.sqrt(plane_strain_modulus() * DEPTH**2 / 12.0 / (RHO * LENGTH**4))
    return 2.0 * math.pi / omega


def timoshenko_period(elements: int = 400) -> float:
    """First-mode period of the clamped-free Timoshenko beam (s), per unit depth: linear
    elements for deflection and rotation, the shear strain at the element's midpoint."""
    from scipy.linalg import eigh

    le = LENGTH / elements
    area, inertia = DEPTH, DEPTH**3 / 12.0
    shear = E / (2.0 * (1.0 + NU)) * 10.0 * (1.0 + NU) / (12.0 + 11.0 * NU) * area
    bend = plane_strain_modulus() * inertia
    n = 2 * (elements + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    curvature = np.array([0.0, -1.0 / le, 0.0, 1.0 / le])
    strain = np.array([-1.0 / le, -0.5, 1.0 / le, -0.5])
    lumped = le / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
    for k in range(elements):
        dofs = np.arange(2 * k, 2 * k + 4)  # (w1, theta1, w2, theta2)
        K[np.ix_(dofs, dofs)] += bend * le * np.outer(curvature, curvature)
        K[np.ix_(dofs, dofs)] += shear * le * np.outer(strain, strain)
        M[np.ix_(dofs[[0, 2]], dofs[[0, 2]])] += RHO * area * lumped
        M[np.ix_(dofs[[1, 3]], dofs[[1, 3]])] += RHO * inertia * lumped
    free = np.arange(2, n)  # w = theta = 0 at the root
    omega2 = eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True,
                  subset_by_index=[0, 0])[0]
    return 2.0 * math.pi / math.sqrt(omega2)


def mode_shape(x: np.ndarray) -> np.ndarray:
    """First cantilever mode of Euler-Bernoulli theory, 1 at the tip (x in [0, L])."""
    b = BETA_L / LENGTH
    s = (math.cosh(BETA_L) + math.cos(BETA_L)) / (math.sinh(BETA_L) + math.sin(BETA_L))

    def phi(y: np.ndarray) -> np.ndarray:
        return np.cosh(b * y) - np.cos(b * y) - s * (np.sinh(b * y) - np.sin(b * y))

    return phi(x) / phi(np.array([LENGTH]))[0]


def beam_case(n_depth: int, overrides: list[str] | None = None, periods: float = 1.3
              ) -> Any:
    """The validated case of the beam with ``n_depth`` particles through the depth."""
    from impactsph.loading import apply_overrides, validate_case

    dx = DEPTH / n_depth
    data = {
        "name": f"beam_{n_depth}", "dimension": 2,
        "materials": {"steel": {"model": "elastic", "density": RHO, "youngs_modulus": E,
                                "poisson_ratio": NU}},
        "bodies": [{"name": "beam", "material": "steel", "velocity": [0.0, 0.0],
                    "geometry": {"origin": [-ROOT_COLUMNS * dx, -DEPTH / 2],
                                 "size": [LENGTH + ROOT_COLUMNS * dx, DEPTH], "spacing": dx},
                    "clamped": {"origin": [-(ROOT_COLUMNS + 1) * dx, -DEPTH],
                                "size": [(ROOT_COLUMNS + 1) * dx, 2 * DEPTH]}}],
        "kernel": {"h_over_dx": 1.3},
        "viscosity": {"scheme": "av", "alpha1": 1.0, "alpha2": 1.0},
        "time": {"end": periods * euler_bernoulli_period(), "wave_speed": "p_wave"},
        "output": {"figures": False, "history_every": 50}}
    return validate_case(apply_overrides(data, overrides or []))


def measure(n_depth: int, overrides: list[str] | None = None, periods: float = 1.3
            ) -> dict[str, Any]:
    """Run the beam for ``periods`` Euler-Bernoulli periods and measure its first period
    (twice the time between the zero crossings of the tip deflection at about T/2 and T: the
    run must last past T, so 1.3 leaves room for a period 25% long)."""
    from impactsph import Simulation

    case = beam_case(n_depth, overrides, periods)
    sim = Simulation(case)
    s = sim.state
    free = ~s.clamped
    s.velocity[free, 1] = TIP_SPEED * mode_shape(np.clip(s.position[free, 0], 0.0, None))
    dx = DEPTH / n_depth
    tip = np.flatnonzero(s.position[:, 0] > LENGTH - dx)
    y0 = float(s.position[tip, 1].mean())
    e0 = s.kinetic_energy()
    times, deflection, energy = [], [], []

    def record(sim: Any) -> None:
        times.append(sim.state.time)
        deflection.append(float(sim.state.position[tip, 1].mean()) - y0)
        if sim.state.step % 50 == 0:
            energy.append(sim.state.kinetic_energy() + sim.state.internal_energy())

    start = time.perf_counter()
    sim.run(callback=record)
    t, y = np.array(times), np.array(deflection)
    sign = np.flatnonzero(np.sign(y[1:]) != np.sign(y[:-1]))
    crossings = [float(t[k] - y[k] * (t[k + 1] - t[k]) / (y[k + 1] - y[k])) for k in sign]
    crossings = [c for c in crossings if c > 0.1 * euler_bernoulli_period()]
    period = 2.0 * (crossings[1] - crossings[0]) if len(crossings) > 1 else math.nan
    reference, classical = timoshenko_period(), euler_bernoulli_period()
    stab = sim.case.stabilisation  # as resolved ("auto" made concrete)
    return {"n_depth": n_depth, "overrides": overrides or [], "particles": s.n,
            "gradient_correction": stab.gradient_correction, "hourglass": stab.hourglass,
            "period": period, "timoshenko_period": reference,
            "euler_bernoulli_period": classical,
            "error_vs_timoshenko": period / reference - 1.0,
            "error_vs_euler_bernoulli": period / classical - 1.0,
            "peak_tip_deflection": float(np.abs(y).max()),
            "total_energy_relative_error": float(np.max(np.abs(np.array(energy) - e0)) / e0),
            "steps": s.step, "wall_seconds": time.perf_counter() - start}


def set_beam(nu: float, slenderness: float) -> None:
    """Set the beam's Poisson's ratio and L/H (module constants the case and the theory
    read) for this process."""
    global NU, LENGTH
    NU, LENGTH = float(nu), float(slenderness) * DEPTH


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("n_depth", nargs="+", type=positive_int, help="particles through the depth")
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    help="a case override, e.g. stabilisation.hourglass=1.0")
    ap.add_argument("--formulation", choices=("updated_lagrangian", "total_lagrangian"),
                    default=None, help="the case's formulation (default: the case's, "
                    "updated_lagrangian)")
    ap.add_argument("--nu", type=float, default=NU,
                    help="Poisson's ratio (default 0.3; issue 11's plate: 0.4)")
    ap.add_argument("--slenderness", type=float, default=LENGTH / DEPTH,
                    help="L/H (default 12; issue 11's plate: 10)")
    args = ap.parse_args(argv)
    set_beam(args.nu, args.slenderness)
    if args.formulation is not None:
        args.overrides.append(f"formulation={args.formulation}")
    for n in args.n_depth:
        print(json.dumps({**measure(n, args.overrides), "nu": NU,
                          "slenderness": LENGTH / DEPTH}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
