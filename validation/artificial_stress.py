"""The artificial stress against the tensile instability (``stabilisation.artificial_stress =
epsilon``; Monaghan 2000, Gray, Monaghan & Swift 2001; docs/stabilisation.md), measured with
and without it on three set-ups.

**The tension rod.**  An elastic rod of soft material (rho = 1000 kg/m^3, E = 10 MPa, nu = 0,
so that the bar, plate and P-wave speeds are all ``c = sqrt(E/rho) = 100 m/s``), L = 0.1 m
long (1D, or 2D plane strain 8 mm wide), moves at V = 2 m/s along its axis away from three
columns of clamped particles (held at rest) behind its left end.  In the frame of the rod the
clamp pulls its end at -V: a tensile front (strain V/c = 2%, stress rho c V = 0.2 MPa) runs
along the rod at c, and behind it the rod is at rest.  The front's speed is measured between
two stations, L/4 and 3L/4 from the clamp, as the times at which the mean velocity of the
station's column of particles falls through V/2.  The rod stays whole if no two particles that
were neighbours at the start (closer than 1.5 dx) are ever farther apart than 2.5 h, and no
two particles come closer than 0.3 dx (no clumping).

**The rod in axisymmetry** (``rod-axi``): the same rod as a cylinder of radius 4 mm along
the axis (``two_dimensional = "axisymmetric"``, the rod along y), pulled the same way; only
its integrity is measured (as for the rod).

**The colliding rubber rings** (Monaghan 2000, Gray et al. 2001 section 6.2): two rings of
inner radius 3 cm and outer radius 4 cm (``geometry.type = "ring"``), 4 mm apart, each moving
towards the other at 0.059 c0.  The material is theirs in scaled form: ``P = c0^2 (rho -
rho0)`` (the linear EOS with K = rho0 c0^2) and the shear modulus ``mu = 0.22 rho0 c0^2``; in
SI, a soft rubber-like solid with rho0 = 1200 kg/m^3 and c0 = 100 m/s: K = 12 MPa,
mu = 2.64 MPa, E = 7.38 MPa, nu = 0.3975; the rings meet at 11.8 m/s.  The time step and the
viscosity use the P-wave speed ``sqrt((K + 4/3 mu)/rho) = 114 m/s``.  Measured: the centres of
mass' velocities (the rebound), whether each ring stays whole (as for the rod), momentum and
total energy.

**Cost.**  A 2D block of 50 x 50 particles in uniform expansion (tension), a few hundred
steps with and without the artificial stress, one thread, best of three alternating rounds.

Usage::

    .venv/bin/python validation/artificial_stress.py rod [--dim 1 2] [--spacing 1e-3 5e-4]
    .venv/bin/python validation/artificial_stress.py rod-axi [--spacing 1e-3 5e-4]
    .venv/bin/python validation/artificial_stress.py rings [--spacing 2e-3 1e-3]
    .venv/bin/python validation/artificial_stress.py cost [--steps 300]

each with ``--epsilon 0 0.3`` (the default); every line printed is one run (JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from impactsph import Simulation
from impactsph.errors import SimulationError
from impactsph.kernels import artificial_stress_moment, gradient_moment
from impactsph.loading import validate_case

H_OVER_DX = 1.3
EPSILON = 0.3
#: the stabilisation the set-ups run with besides the artificial stress: "plain" is the
#: paper's scheme (no gradient correction, no hourglass control), "defaults" the case
#: defaults (for these elastic bodies: the correction of the forces and hourglass zeta = 2)
SCHEMES = {"plain": {"gradient_correction": "none", "hourglass": 0.0}, "defaults": {},
           # the plain scheme with the artificial stress's smooth part added back
           # (stabilisation.artificial_stress_compensation)
           "compensated": {"gradient_correction": "none", "hourglass": 0.0,
                           "artificial_stress_compensation": True}}



def _scheme(name: str, epsilon: float) -> dict[str, Any]:
    """The ``[stabilisation]`` fields of ``SCHEMES[name]`` (the compensation only where there
    is an artificial stress to compensate)."""
    fields = dict(SCHEMES[name])
    if epsilon == 0.0:
        fields.pop("artificial_stress_compensation", None)
    return fields


# -- the tension rod -------------------------------------------------------------------------
ROD_RHO, ROD_E = 1000.0, 1e7  # kg/m^3, Pa
ROD_C = math.sqrt(ROD_E / ROD_RHO)  # m/s
ROD_LENGTH, ROD_WIDTH = 0.1, 8e-3  # m
ROD_SPEED = 2.0  # m/s
CLAMP_COLUMNS = 3
#: the stations where the front's arrival is timed, as fractions of the length from the clamp
STATIONS = (0.25, 0.75)

# -- the rubber rings ------------------------------------------------------------------------
RING_RHO, RING_C0 = 1200.0, 100.0  # kg/m^3, m/s
RING_K = RING_RHO * RING_C0**2  # Pa: P = c0^2 (rho - rho0)
RING_MU = 0.22 * RING_RHO * RING_C0**2  # Pa
RING_E = 9.0 * RING_K * RING_MU / (3.0 * RING_K + RING_MU)
RING_NU = (3.0 * RING_K - 2.0 * RING_MU) / (2.0 * (3.0 * RING_K + RING_MU))
RING_SPEED = 0.059 * RING_C0  # m/s, each ring
INNER_RADIUS, OUTER_RADIUS, RING_GAP = 0.03, 0.04, 0.004  # m


def lattice_moments(dim: int, h_over_dx: float = H_OVER_DX, exponent: float = 4.0
                    ) -> tuple[float, float]:
    """``(M, M_f)``: the first moment ``M = -sum_j V_j (x_j^2 / r_j) dW/dr`` of the kernel
    gradient over a regular lattice (:func:`impactsph.kernels.gradient_moment`), and the same
    sum weighted by the artificial stress's ``f_j^n = (W(r_j) / W(dx))^n``
    (:func:`impactsph.kernels.artificial_stress_moment`).

    For a long wave on the lattice, the SPH gradient of a linear field is ``M`` times the
    exact one, and the artificial-stress sum of a linearly varying ``R`` is ``M_f rho grad R``;
    in tension ``R = -epsilon sigma / rho^2``, so the momentum equation sees ``(M - epsilon
    M_f) grad sigma`` and the stress rate ``M grad v``: the discrete long-wave speed in
    tension is ``c sqrt(M (M - epsilon M_f))`` (:func:`discrete_tension_speed`)."""
    return (gradient_moment(h_over_dx, dim),
            artificial_stress_moment(h_over_dx, dim, exponent))


def discrete_tension_speed(dim: int, epsilon: float) -> float:
    """The long-wave speed of the discrete equations in tension (m/s, the rod's material):
    ``c sqrt(M (M - epsilon M_f))`` (:func:`lattice_moments`)."""
    M, Mf = lattice_moments(dim)
    return ROD_C * math.sqrt(M * (M - epsilon * Mf))


def rod_case(dim: int, spacing: float, epsilon: float, end_fraction: float = 1.0,
             scheme: str = "plain") -> Any:
    """The tension rod (module docstring), run to ``end_fraction * L / c``, with the
    stabilisation ``SCHEMES[scheme]``."""
    dx = spacing
    return validate_case({
        "name": f"rod_{dim}d", "dimension": dim,
        "materials": {"m": {"model": "elastic" if dim > 1 else "bar", "density": ROD_RHO,
                            "youngs_modulus": ROD_E, "poisson_ratio": 0.0}},
        "bodies": [{
            "name": "rod", "material": "m", "velocity": [ROD_SPEED] + [0.0] * (dim - 1),
            "geometry": {"origin": [-CLAMP_COLUMNS * dx] + [0.0] * (dim - 1),
                         "size": [ROD_LENGTH + CLAMP_COLUMNS * dx] + [ROD_WIDTH] * (dim - 1),
                         "spacing": dx},
            "clamped": {"origin": [-CLAMP_COLUMNS * dx - 0.1 * dx] + [-1.0] * (dim - 1),
                        "size": [CLAMP_COLUMNS * dx] + [2.0] * (dim - 1)}}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "stabilisation": {"artificial_stress": epsilon,
                          **_scheme(scheme, epsilon)},
        "time": {"end": end_fraction * ROD_LENGTH / ROD_C},
        "output": {"figures": False, "history_every": 1000}})


class Integrity:
    """Whether a body stays whole: the largest distance between particles of one body that
    were neighbours at the start (closer than 1.5 dx), over ``h``, and the smallest distance
    between any two particles, over dx, both over the samples taken."""

    def __init__(self, sim: Simulation, spacing: float):
        s = sim.state
        pairs = cKDTree(s.position).query_pairs(1.5 * spacing, output_type="ndarray")
        self.pairs = pairs[s.body[pairs[:, 0]] == s.body[pairs[:, 1]]]
        self.h = float(s.smoothing_length.max())
        self.spacing = spacing
        self.max_separation = 0.0  # over h
        self.min_distance = math.inf  # over dx

    def sample(self, x: np.ndarray) -> None:
        d = np.linalg.norm(x[self.pairs[:, 0]] - x[self.pairs[:, 1]], axis=1)
        self.max_separation = max(self.max_separation, float(d.max()) / self.h)
        nearest = cKDTree(x).query(x, k=2)[0][:, 1]
        self.min_distance = min(self.min_distance, float(nearest.min()) / self.spacing)


def _crossing(t: np.ndarray, v: np.ndarray, level: float) -> float:
    """The first time at which ``v`` falls through ``level`` (linear between samples)."""
    below = np.flatnonzero(v < level)
    if below.size == 0 or below[0] == 0:
        return math.nan
    k = below[0]
    return float(t[k - 1] + (level - v[k - 1]) * (t[k] - t[k - 1]) / (v[k] - v[k - 1]))


def run_sampled(sim: Simulation, every: int, sample: Callable[[Simulation], None],
                each_step: Callable[[Simulation], None] | None = None
                ) -> tuple[str | None, float]:
    """Run ``sim`` to its end: ``each_step(sim)`` after every step, ``sample(sim)`` every
    ``every`` steps and once at the end (after a failure too).  Returns the failure's message
    (None if the run finished) and the seconds it took."""
    def callback(sim: Simulation) -> None:
        if each_step is not None:
            each_step(sim)
        if sim.state.step % every == 0:
            sample(sim)

    failure = None
    start = time.perf_counter()
    try:
        sim.run(callback=callback)
    except SimulationError as exc:
        failure = str(exc)
    sample(sim)
    return failure, time.perf_counter() - start


def measure_rod(dim: int, spacing: float, epsilon: float, end_fraction: float = 1.0,
                every: int = 5, scheme: str = "plain") -> dict[str, Any]:
    """Run the tension rod: its front speed (m/s) between the stations, against ``c`` and the
    discrete long-wave speed, and its integrity (:class:`Integrity`, sampled every ``every``
    steps)."""
    sim = Simulation(rod_case(dim, spacing, epsilon, end_fraction, scheme))
    s = sim.state
    x0 = s.position[:, 0].copy()
    columns = []
    for fraction in STATIONS:
        nearest = x0[np.argmin(np.abs(x0 - fraction * ROD_LENGTH))]
        columns.append(np.abs(x0 - nearest) < 1e-3 * spacing)
    where = [float(x0[c].mean()) for c in columns]
    integrity = Integrity(sim, spacing)
    times, speeds = [], []

    def record(sim: Simulation) -> None:
        times.append(sim.state.time)
        speeds.append([float(sim.state.velocity[c, 0].mean()) for c in columns])

    failure, seconds = run_sampled(sim, every, lambda sim: integrity.sample(sim.state.position),
                                   record)
    t, v = np.array(times), np.array(speeds)
    arrival = [_crossing(t, v[:, k], 0.5 * ROD_SPEED) for k in range(len(STATIONS))]
    speed = (where[1] - where[0]) / (arrival[1] - arrival[0])
    theory = discrete_tension_speed(dim, epsilon)
    return {"set_up": "rod", "scheme": scheme, "dimension": dim, "spacing": spacing,
            "epsilon": epsilon,
            "particles": s.n, "steps": s.step, "front_speed": speed,
            "error_vs_c": speed / ROD_C - 1.0, "discrete_speed": theory,
            "error_vs_discrete": (speed - theory) / ROD_C,
            "max_separation_over_h": integrity.max_separation,
            "min_distance_over_dx": integrity.min_distance,
            "seconds": seconds, "failure": failure}


def axisymmetric_rod_case(spacing: float, epsilon: float) -> Any:
    """The tension rod as a cylinder of radius ``ROD_WIDTH / 2`` along the axis (y) in
    axisymmetry, run to ``L / c``."""
    dx = spacing
    return validate_case({
        "name": "rod_axisymmetric", "dimension": 2, "two_dimensional": "axisymmetric",
        "materials": {"m": {"model": "elastic", "density": ROD_RHO, "youngs_modulus": ROD_E,
                            "poisson_ratio": 0.0}},
        "bodies": [{
            "name": "rod", "material": "m", "velocity": [0.0, ROD_SPEED],
            "geometry": {"origin": [0.0, -CLAMP_COLUMNS * dx],
                         "size": [ROD_WIDTH / 2, ROD_LENGTH + CLAMP_COLUMNS * dx],
                         "spacing": dx},
            "clamped": {"origin": [-1.0, -CLAMP_COLUMNS * dx - 0.1 * dx],
                        "size": [2.0, CLAMP_COLUMNS * dx]}}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "stabilisation": {"artificial_stress": epsilon},
        "time": {"end": ROD_LENGTH / ROD_C},
        "output": {"figures": False, "history_every": 1000}})


def measure_axisymmetric_rod(spacing: float, epsilon: float, every: int = 5
                             ) -> dict[str, Any]:
    """Run the rod in axisymmetry: its integrity (:class:`Integrity`, sampled every
    ``every`` steps) and energy error."""
    sim = Simulation(axisymmetric_rod_case(spacing, epsilon))
    integrity = Integrity(sim, spacing)
    failure, seconds = run_sampled(sim, every, lambda sim: integrity.sample(sim.state.position))
    summary = sim.summary()
    return {"set_up": "rod-axi", "spacing": spacing, "epsilon": epsilon,
            "particles": sim.state.n, "steps": sim.state.step,
            "max_separation_over_h": integrity.max_separation,
            "min_distance_over_dx": integrity.min_distance,
            "total_energy_relative_error": summary["total_energy_relative_error"],
            "seconds": seconds, "failure": failure}


def rings_case(spacing: float, epsilon: float, end: float, scheme: str = "plain") -> Any:
    """The colliding rubber rings (module docstring), run to ``end`` (s), with the
    stabilisation ``SCHEMES[scheme]``."""
    centre = OUTER_RADIUS + 0.5 * RING_GAP

    def ring(side: float) -> dict[str, Any]:
        return {"type": "ring", "centre": [side * centre, 0.0], "inner_radius": INNER_RADIUS,
                "outer_radius": OUTER_RADIUS, "spacing": spacing}

    return validate_case({
        "name": "rubber_rings", "dimension": 2,
        "materials": {"rubber": {"model": "elastic", "density": RING_RHO,
                                 "youngs_modulus": RING_E, "poisson_ratio": RING_NU}},
        "bodies": [{"name": "left", "material": "rubber", "velocity": [RING_SPEED, 0.0],
                    "geometry": ring(-1.0)},
                   {"name": "right", "material": "rubber", "velocity": [-RING_SPEED, 0.0],
                    "geometry": ring(1.0)}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "stabilisation": {"artificial_stress": epsilon, **_scheme(scheme, epsilon)},
        "time": {"end": end, "wave_speed": "p_wave"},
        "output": {"figures": False, "history_every": 1000}})


def measure_rings(spacing: float, epsilon: float, end: float = 0.016, every: int = 20,
                  scheme: str = "plain") -> dict[str, Any]:
    """Run the rubber rings to ``end`` (s), sampling every ``every`` steps: the centres of
    mass' velocities along x (m/s), their distance (m), the integrity of the rings
    (:class:`Integrity`), momentum and total energy."""
    sim = Simulation(rings_case(spacing, epsilon, end, scheme))
    s = sim.state
    left = s.body == 0
    m = s.mass
    e0 = s.kinetic_energy() + s.internal_energy()
    scale = float(m @ np.linalg.norm(s.velocity, axis=1))
    integrity = Integrity(sim, spacing)
    rows = []

    def sample(sim: Simulation) -> None:
        st = sim.state
        vl = float(m[left] @ st.velocity[left, 0] / m[left].sum())
        vr = float(m[~left] @ st.velocity[~left, 0] / m[~left].sum())
        xl = float(m[left] @ st.position[left, 0] / m[left].sum())
        xr = float(m[~left] @ st.position[~left, 0] / m[~left].sum())
        energy = (st.kinetic_energy() + st.internal_energy() - e0) / e0
        momentum = float(np.abs(st.momentum()).max()) / scale
        rows.append((st.time, vl, vr, xr - xl, energy, momentum))
        integrity.sample(st.position)

    failure, seconds = run_sampled(sim, every, sample)
    r = np.array(rows)
    return {"set_up": "rings", "scheme": scheme, "spacing": spacing,
            "epsilon": epsilon, "particles": s.n,
            "steps": s.step, "time": s.time,
            "velocity_left": r[-1, 1], "velocity_right": r[-1, 2],
            "restitution": (r[-1, 2] - r[-1, 1]) / (2.0 * RING_SPEED),
            "slowest_approach": float(np.min(r[:, 1] - r[:, 2])) / (2.0 * RING_SPEED),
            "centres_distance": r[:, 3].tolist(), "times": r[:, 0].tolist(),
            "max_separation_over_h": integrity.max_separation,
            "min_distance_over_dx": integrity.min_distance,
            "energy_error": float(np.abs(r[:, 4]).max()),
            "momentum_error": float(r[:, 5].max()),
            "seconds": seconds, "failure": failure}


def cost(steps: int = 300, rounds: int = 3, side: int = 50,
         epsilons: tuple[float, ...] = (0.0, EPSILON)) -> dict[float, float]:
    """Seconds per step of a ``side x side`` 2D block in uniform expansion (tension), best of
    ``rounds`` runs of ``steps`` steps, the settings in turn round after round."""
    dx = 1e-3

    def block(epsilon: float) -> Simulation:
        case = validate_case({
            "name": "block", "dimension": 2,
            "materials": {"m": {"model": "elastic", "density": ROD_RHO,
                                "youngs_modulus": ROD_E, "poisson_ratio": 0.3}},
            "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0],
                        "geometry": {"origin": [0.0, 0.0], "size": [side * dx] * 2,
                                     "spacing": dx}}],
            "kernel": {"h_over_dx": H_OVER_DX},
            "stabilisation": {"artificial_stress": epsilon},
            "time": {"end": 1.0, "max_steps": steps},
            "output": {"figures": False, "history_every": 1000}})
        sim = Simulation(case)
        centre = side * dx / 2.0
        sim.state.velocity[:] = 20.0 * (sim.state.position - centre)  # 2%/ms expansion
        return sim

    best = dict.fromkeys(epsilons, math.inf)
    for _ in range(rounds):
        for epsilon in epsilons:
            sim = block(epsilon)
            start = time.perf_counter()
            sim.run()
            best[epsilon] = min(best[epsilon], (time.perf_counter() - start) / steps)
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set_up", choices=("rod", "rod-axi", "rings", "cost"))
    ap.add_argument("--epsilon", type=float, nargs="+", default=[0.0, EPSILON])
    ap.add_argument("--dim", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--spacing", type=float, nargs="+")
    ap.add_argument("--end", type=float, default=0.016, help="the rings' end time (s)")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--scheme", choices=sorted(SCHEMES), default="plain",
                    help="the rest of the stabilisation: the paper's scheme (plain) or the "
                    "case defaults")
    args = ap.parse_args(argv)
    if args.set_up == "cost":
        best = cost(args.steps, epsilons=tuple(args.epsilon))
        plain = best.get(0.0)
        for epsilon, seconds in best.items():
            print(json.dumps({"set_up": "cost", "epsilon": epsilon, "seconds_per_step": seconds,
                              "ratio": seconds / plain if plain else None}), flush=True)
        return 0
    for spacing in args.spacing or ([1e-3, 5e-4] if args.set_up.startswith("rod")
                                    else [2e-3]):
        for epsilon in args.epsilon:
            if args.set_up == "rod-axi":
                print(json.dumps(measure_axisymmetric_rod(spacing, epsilon)), flush=True)
            elif args.set_up == "rod":
                for dim in args.dim:
                    print(json.dumps(measure_rod(dim, spacing, epsilon,
                                                 scheme=args.scheme)), flush=True)
            else:
                result = measure_rings(spacing, epsilon, args.end, scheme=args.scheme)
                del result["centres_distance"], result["times"]
                print(json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
