"""Two elastic spheres in a head-on collision, total-Lagrangian with its penalty contact
(docs/stabilisation.md, "Contact between total-Lagrangian bodies"), against Hertz's impact
theory (Johnson, *Contact Mechanics* (1985), section 11.4): for spheres of reduced mass
``m* = m/2``, effective radius ``R* = R/2`` and contact modulus ``E* = E / (2 (1 - nu^2))``
meeting at the relative speed ``v``::

    delta_max = (15 m* v^2 / (16 E* R*^(1/2)))^(2/5)       the greatest approach
    F_max     = 4/3 E* R*^(1/2) delta_max^(3/2)             the greatest force
    t_c       = 2.94 delta_max / v                          the contact time

valid while the contact lasts many times the time a wave takes to cross a sphere (here about
14 ``R / c``) and the contact radius stays small against ``R`` (about 0.2 ``R`` here).  The
spheres are steel-like, elastic with a linear equation of state, 10 mm across, at +-50 m/s
(``--speed``), starting a quarter spacing apart; a run lasts until 1.6 of Hertz's contact time
after the surfaces meet, and one that ends in contact is refused.

    .venv/bin/python validation/hertz_spheres.py 6 10 15 [--arrangement lattice|shells]
        [--formulation total_lagrangian|updated_lagrangian] [--speed 50] [--set PATH=VALUE]
        [--json PATH]

The arguments are the radius in particle spacings.  Prints, per resolution, the contact time,
the greatest contact force and the rebound against Hertz's, and the energy error.

Measured (docs/stabilisation.md, "Contact between total-Lagrangian bodies"): with the default
penalty stiffness (k = 4) the contact time is within 1% of Hertz's from 10 spacings per
radius at 100 m/s apart (+15.7% and +5.9% at 6 and 8), but at 25 m/s apart it stalls at +10%
(15 and 20 spacings); with Hertz's law between the particles (k = 1) it is 22-37% long at
100 m/s and does not converge; with the cubic lattice's spheres (``--arrangement lattice``,
their flat polar facets) 22-24% short.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
from _args import positive_float

RADIUS = 5e-3  # m
SPEED = 50.0  # m/s each, 100 m/s apart
E, NU, RHO = 200e9, 0.3, 7800.0


def hertz(speed: float = SPEED) -> dict[str, float]:
    """Hertz's contact time (s), greatest force (N) and approach (m) for the two spheres, each
    at ``speed`` (m/s) towards the other."""
    mass = RHO * 4.0 / 3.0 * math.pi * RADIUS**3
    m_star, r_star, e_star = mass / 2.0, RADIUS / 2.0, E / (2.0 * (1.0 - NU**2))
    v = 2.0 * speed
    delta = (15.0 * m_star * v**2 / (16.0 * e_star * math.sqrt(r_star))) ** 0.4
    return {"contact_time": 2.94 * delta / v,
            "max_force": 4.0 / 3.0 * e_star * math.sqrt(r_star) * delta**1.5,
            "max_approach": delta, "contact_radius": math.sqrt(r_star * delta)}


#: the gap between the spheres' surfaces at the start, in spacings
GAP = 0.25


def case(radius_in_spacings: float, end: float, arrangement: str = "shells",
         formulation: str = "total_lagrangian", speed: float = SPEED) -> dict:
    dx = RADIUS / radius_in_spacings
    centre = RADIUS + 0.5 * GAP * dx
    material = {"model": "elastic", "density": RHO, "youngs_modulus": E, "poisson_ratio": NU,
                "eos": "linear"}
    return {
        "name": "hertz_spheres", "dimension": 3, "formulation": formulation,
        "materials": {"steel": material},
        "bodies": [{"name": name, "material": "steel", "velocity": [0.0, 0.0, speed],
                    "geometry": {"type": "sphere", "centre": [0.0, 0.0, z], "radius": RADIUS,
                                 "spacing": dx, "arrangement": arrangement}}
                   for name, z, speed in (("lower", -centre, speed),
                                          ("upper", centre, -speed))],
        "kernel": {"h_over_dx": 1.3},
        "viscosity": {"scheme": "av", "alpha1": 1.0, "alpha2": 1.0},
        "time": {"end": end, "courant": 0.3, "wave_speed": "p_wave"},
        "output": {"figures": False, "history_every": 1}}


def measure(radius_in_spacings: float, arrangement: str = "shells",
            formulation: str = "total_lagrangian", speed: float = SPEED,
            overrides: list[str] | None = None) -> dict:
    from impactsph import Simulation
    from impactsph.loading import apply_overrides, validate_case

    theory = hertz(speed)
    closing = GAP * RADIUS / radius_in_spacings / (2.0 * speed)  # until the surfaces touch
    data = case(radius_in_spacings, closing + 1.6 * theory["contact_time"], arrangement,
                formulation, speed)
    sim = Simulation(validate_case(apply_overrides(data, overrides or [])))
    start = time.perf_counter()
    sim.run()
    seconds = time.perf_counter() - start
    history = sim.record.history
    t = np.array([row["time"] for row in history])
    force = np.array([row["contact_force_upper_z"] for row in history])  # pushed up: > 0
    touching = np.flatnonzero(force > 1e-3 * theory["max_force"])
    if touching.size == 0 or touching[-1] == len(t) - 1:
        raise RuntimeError(f"{radius_in_spacings} spacings, {speed} m/s: the spheres "
                           f"{'never met' if touching.size == 0 else 'are still in contact'} "
                           f"at t = {t[-1]:.4g} s")
    contact_time = float(t[touching[-1]] - t[touching[0]])
    s = sim.state
    upper = s.body == 1
    v_upper = float(np.average(s.velocity[upper, 2], weights=s.mass[upper]))
    summary = sim.summary()
    return {"radius_in_spacings": radius_in_spacings, "arrangement": arrangement,
            "formulation": formulation, "speed": speed, "overrides": overrides or [],
            "particles": int(s.n),
            "steps": int(s.step), "contact_time": contact_time,
            "contact_time_error": contact_time / theory["contact_time"] - 1.0,
            "max_force": float(force.max()),
            "max_force_error": float(force.max()) / theory["max_force"] - 1.0,
            "rebound": v_upper / speed,
            "total_energy_relative_error": summary["total_energy_relative_error"],
            "momentum_drift": summary["momentum_drift"], "wall_seconds": seconds}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("radii", nargs="+", type=positive_float, help="sphere radius in spacings")
    parser.add_argument("--arrangement", choices=("shells", "lattice"), default="shells",
                        help="the spheres' particles (geometry.arrangement; default shells)")
    parser.add_argument("--formulation", choices=("total_lagrangian", "updated_lagrangian"),
                        default="total_lagrangian",
                        help="the case's formulation (default total_lagrangian; "
                        "updated_lagrangian: the kernel's contact, the elastic defaults)")
    parser.add_argument("--speed", type=float, default=SPEED,
                        help=f"each sphere's speed towards the other, m/s (default {SPEED:g})")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="PATH=VALUE", help="override a case field, as `impactsph run "
                        "--set` does (e.g. contact.penalty_stiffness=1)")
    parser.add_argument("--json", help="write the rows here")
    args = parser.parse_args(argv)
    theory = hertz(args.speed)
    print(f"Hertz: contact time {theory['contact_time'] * 1e6:.3f} us, greatest force "
          f"{theory['max_force']:.4g} N, approach {theory['max_approach'] * 1e3:.4f} mm, "
          f"contact radius {theory['contact_radius'] / RADIUS:.3f} R")
    rows = []
    for radius in args.radii:
        row = measure(radius, args.arrangement, args.formulation, args.speed, args.overrides)
        rows.append(row)
        print(json.dumps(row), flush=True)
    if args.json:
        from impactsph.output import write_study

        write_study(args.json, {"hertz": theory, "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
