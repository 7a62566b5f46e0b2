"""An independent reference for the Taylor bar: explicit finite elements, to settle what the
SPH answers converge to (docs/validation.md: the plane-strain footprint, "Why the plane-strain
footprint moves so much"; the copper cylinder's length against the measured one).

The same physics as ``impactsph run``, discretised the way a Lagrangian hydrocode does
(Wilkins' HEMP; Hallquist's DYNA2D), not with particles:

- bilinear quadrilaterals (Q4), 2 x 2 Gauss points, mean dilatation (Nagtegaal, Parks & Rice
  1974; Hughes' B-bar): the volumetric strain rate is the element's mean, so the nearly
  incompressible plastic flow does not lock, and full integration has no hourglass modes;
- plane strain, or axisymmetry (x the radius: the hoop rate ``v_r / r`` and the hoop stress
  in the forces, every volume weighted by ``r``);
- updated Lagrangian, hypoelastic: Jaumann rate of the deviatoric stress (paper eqs 14-16);
  the package's own return map (``impactsph.models.strength.hardening.hardening_return``:
  perfectly plastic von Mises for the paper's iron, Johnson-Cook with the rate and the
  temperature raised by ``beta w_p / c_p`` for a library material); the package's
  Mie-Gruneisen pressure with the element's density and specific energy, the energy
  equation solved for the new pressure (implicit in e, exact for a pressure linear in e);
- von Neumann-Richtmyer bulk viscosity in compression only (DYNA's default coefficients,
  linear 0.06 and quadratic 1.5, on the element length below), which acts on the volumetric
  rate alone, never on shear;
- central differences, lumped masses, the time step at a Courant number of 0.5 on the
  element's length taken as its area over its longer diagonal (h / sqrt 2 for a square of
  side h) and the P-wave speed;
- half the bar, x >= 0, with the symmetry plane (or the axis) x = 0; the rigid wall y = 0
  frictionless: a node that would cross it lands on it (its velocity in that step is what
  takes it there), so the bottom row stops dead in the first step: that kinetic energy
  (about 1/(2 n_along) of the whole) is lost, and the energy error is reported net of it.

What it reports at the snapshot times: ``L_f/L_0`` (highest node less lowest: a bar that has
rebounded has left the wall), the footprint
(outermost node on the wall, over the half-width; 0 once the bar has left the wall), where
the foot's rim (the bottom outer corner) is, the widest section (outermost node at any
height), the plastic work (J/m of the whole bar in plane strain, J per radian in
axisymmetry, as the SPH run's ``plastic_work``) and the energy balance.  Nodes are the body's
boundary, so no half spacing is added.  ``footprint_half_width_ratio_fixed``: the SPH
measure of the same name (``impactsph.problems.taylor``, a band of fixed height): the
outermost point of the outline within ``FOOT_LIFT`` half-widths of the wall, the outline's
crossing of that height interpolated along its edges.

    .venv/bin/python validation/taylor_fem.py 8 16 32 64       # the paper's bar, plane strain
    .venv/bin/python validation/taylor_fem.py 8 16 --sph runs/taylor runs/taylor-x2  # drawn over
    .venv/bin/python validation/taylor_fem.py 8 16 32 --case taylor_axisymmetric  # its cylinder
    .venv/bin/python validation/taylor_fem.py 10 20 40 --test ofhc_copper:190   # axisymmetric

``N`` is the number of elements across the half-width (the SPH bar at x1 has 10.5 particles
there).  This file is a validation tool, not part of the package: there is no maintained
Python library for explicit large-strain elastoplastic dynamics with a rigid wall.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np
from _args import positive_int

from impactsph.loading import load_case, validate_case
from impactsph.materials import resolve_material
from impactsph.models.columns import (
    EQUIVALENT_PLASTIC_STRAIN,
    PLASTIC_STRAIN_RATE,
    TEMPERATURE,
)
from impactsph.models.eos.mie_gruneisen import mie_gruneisen_pressure
from impactsph.models.strength.hardening import hardening_return, thermal_factor
from impactsph.output import write_study
from impactsph.problems.taylor import FOOT_LIFT

Q_LINEAR, Q_QUADRATIC = 0.06, 1.5
COURANT = 0.5
G = 1.0 / math.sqrt(3.0)
GAUSS = np.array([[-G, -G], [G, -G], [G, G], [-G, G]])
#: N_a and dN_a/dxi, dN_a/deta at each Gauss point: (gp, node) and (gp, node, 2)
SHAPE = np.array([[(1 - xi) * (1 - eta) / 4, (1 + xi) * (1 - eta) / 4,
                   (1 + xi) * (1 + eta) / 4, (1 - xi) * (1 + eta) / 4] for xi, eta in GAUSS])
DSHAPE = np.array([[[-(1 - eta) / 4, -(1 - xi) / 4], [(1 - eta) / 4, -(1 + xi) / 4],
                    [(1 + eta) / 4, (1 + xi) / 4], [-(1 + eta) / 4, (1 - xi) / 4]]
                   for xi, eta in GAUSS])
#: the material vector's entries
(RHO0, SHEAR, A0, B0, C0, GRUNEISEN, FLOW_A, FLOW_B, FLOW_N, FLOW_C, RATE0, THERMAL_M,
 T_REF, T_MELT, HEAT_PER_WORK, T_INITIAL) = range(16)
STATE_WIDTH = max(EQUIVALENT_PLASTIC_STRAIN, PLASTIC_STRAIN_RATE, TEMPERATURE) + 1


@dataclass
class Bar:
    """A Taylor bar: its half-width (or radius), length, speed, material vector and model."""

    name: str
    half_width: float
    length: float
    speed: float
    material: np.ndarray
    axisymmetric: bool
    end: float
    snapshots: tuple[float, ...] = field(default=())


def material_vector(case_material, name: str = "bar") -> np.ndarray:
    """The entries above from a validated case material: Mie-Gruneisen or linear pressure and
    a perfectly plastic (``elastic_plastic``) or Johnson-Cook strength."""
    m = resolve_material(name, case_material)
    out = np.zeros(16)
    out[RHO0], out[SHEAR] = m.density, m.shear_modulus
    if m.eos == "mie_gruneisen":
        out[A0:GRUNEISEN + 1] = m.eos_columns
    elif m.eos == "linear":  # P = K (rho/rho0 - 1): Mie-Gruneisen with a0 = K and no more
        out[A0] = m.bulk_modulus
    else:
        sys.exit(f"taylor_fem: eos {m.eos!r} is not supported (mie_gruneisen, linear)")
    if m.model == "elastic_plastic":
        out[FLOW_A], out[FLOW_N], out[RATE0] = m.strength_columns[0], 1.0, 1.0
        out[THERMAL_M] = 1.0  # T_melt = T_ref = 0: no thermal softening
    elif m.model == "johnson_cook":
        out[FLOW_A:T_MELT + 1] = m.strength_columns
        out[HEAT_PER_WORK] = m.taylor_quinney / m.specific_heat if m.specific_heat else 0.0
    else:
        sys.exit(f"taylor_fem: strength {m.model!r} is not supported")
    out[T_INITIAL] = m.temperature
    return out


def paper_bar(name: str = "taylor") -> Bar:
    """The paper's Example 2: ``taylor`` (iron, plane strain, the whole width from x = -B/2)
    or ``taylor_axisymmetric`` (the cylinder's half-section from the axis), to 50 us."""
    case = load_case(name)
    body = case.bodies[0]
    axisymmetric = case.two_dimensional == "axisymmetric"
    half_width = body.geometry.size[0] if axisymmetric else 0.5 * body.geometry.size[0]
    return Bar(name, half_width, body.geometry.size[1], -body.velocity[1],
               material_vector(case.materials[body.material]), axisymmetric, case.time.end,
               (30e-6, 40e-6, 50e-6))


def measured_bar(material: str, velocity: float, end: float = 100e-6) -> Bar:
    """A test of validation/taylor_measured.toml, as that script's axisymmetric case."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import taylor_measured as tm

    test = next(t for t in tm.tests(True) if t["material"] == material
                and abs(t["velocity"] - velocity) < 0.5)
    case = validate_case(tm.axisymmetric(tm.case_of(test, 20, end)))
    return Bar(f"{material}-{velocity:g}", 0.5 * test["diameter"], test["length"],
               test["velocity"], material_vector(case.materials["bar"]), True, end, (end,))


def mesh(bar: Bar, n_across: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 2) and elements (e, 4, counter-clockwise) of the half bar, ``n_across``
    elements over the half-width and as many along as keep them square."""
    n_along = round(n_across * bar.length / bar.half_width)
    xs = np.linspace(0.0, bar.half_width, n_across + 1)
    ys = np.linspace(0.0, bar.length, n_along + 1)
    nodes = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n_across), np.arange(n_along))
    first = (j * (n_across + 1) + i).ravel()
    elements = np.stack([first, first + 1, first + n_across + 2, first + n_across + 1], 1)
    return nodes, elements.astype(np.int64)


@nb.njit(inline="always", cache=True)
def point_gradient(f, nodes, derivatives, g):
    """``sum_a f_a (x) D_a`` at Gauss point ``g`` (``D`` = ``DSHAPE[g]``: the Jacobian of
    the positions; ``dN[g]``: the gradient of a nodal field) and ``sum_a N_a f_a,0`` (the
    radius, or the radial velocity, there): ``(f0_1, f0_2, f1_1, f1_2, value0)``."""
    g00 = g01 = g10 = g11 = value = 0.0
    for a in range(4):
        f0, f1 = f[nodes[a], 0], f[nodes[a], 1]
        g00 += f0 * derivatives[g, a, 0]
        g01 += f0 * derivatives[g, a, 1]
        g10 += f1 * derivatives[g, a, 0]
        g11 += f1 * derivatives[g, a, 1]
        value += SHAPE[g, a] * f0
    return g00, g01, g10, g11, value


@nb.njit(cache=True)
def lumped_masses(x, elements, rho0, axisymmetric):
    """``m_a = sum_e rho0 int N_a dV`` (dV = r dA in axisymmetry, per radian); element masses."""
    mass = np.zeros(x.shape[0])
    mass_e = np.zeros(elements.shape[0])
    for k in range(elements.shape[0]):
        nodes = elements[k]
        for g in range(4):
            j00, j01, j10, j11, r = point_gradient(x, nodes, DSHAPE, g)
            w = (j00 * j11 - j01 * j10) * (r if axisymmetric else 1.0)
            mass_e[k] += rho0 * w
            for a in range(4):
                mass[nodes[a]] += rho0 * SHAPE[g, a] * w
    return mass, mass_e


@nb.njit(cache=True)
def element_pass(x, v, elements, mass_e, rho, e, S, state, p, dt, M, axisymmetric, update):
    """One element loop: with ``update``, the stresses, plastic state, density and energy
    advance by ``dt`` on the velocities ``v`` (the mid-step ones) in the configuration ``x``
    (the new one); always, the internal nodal forces of the current stresses and the stable
    time step.  Returns (force, dt_stable, plastic work of this step, per radian in
    axisymmetry)."""
    force = np.zeros(x.shape)
    dt_min = 1e30
    plastic = 0.0
    shear = M[SHEAR]
    dN = np.empty((4, 4, 2))
    w = np.empty(4)
    radius = np.empty(4)
    hoop = np.empty(4)  # v_r / r at each point (axisymmetry)
    power = np.empty(4)  # each point's deviatoric power
    S33 = np.zeros((3, 3))
    local = np.zeros(STATE_WIDTH)
    for k in range(elements.shape[0]):
        nodes = elements[k]
        volume = 0.0
        area = 0.0
        for g in range(4):
            j00, j01, j10, j11, r = point_gradient(x, nodes, DSHAPE, g)
            d = j00 * j11 - j01 * j10
            radius[g] = r
            w[g] = d * (r if axisymmetric else 1.0)
            volume += w[g]
            area += d
            for a in range(4):  # dN/dx = J^-T dN/dxi
                dN[g, a, 0] = (j11 * DSHAPE[g, a, 0] - j10 * DSHAPE[g, a, 1]) / d
                dN[g, a, 1] = (-j01 * DSHAPE[g, a, 0] + j00 * DSHAPE[g, a, 1]) / d
        length = area / math.sqrt(max(
            (x[nodes[2], 0] - x[nodes[0], 0]) ** 2 + (x[nodes[2], 1] - x[nodes[0], 1]) ** 2,
            (x[nodes[3], 0] - x[nodes[1], 0]) ** 2 + (x[nodes[3], 1] - x[nodes[1], 1]) ** 2))
        if update:
            div = 0.0
            rho_new = mass_e[k] / volume  # the element's density in the new configuration
            for g in range(4):
                lxx, lxy, lyx, lyy, vr = point_gradient(v, nodes, dN, g)
                hoop[g] = vr / radius[g] if axisymmetric else 0.0
                div += (lxx + lyy + hoop[g]) * w[g]
                w_spin = 0.5 * (lxy - lyx)
                dxy = 0.5 * (lxy + lyx)
                tr = lxx + lyy + hoop[g]
                dxx, dyy, dzz = lxx - tr / 3.0, lyy - tr / 3.0, hoop[g] - tr / 3.0
                sxx, syy, sxy = S[k, g, 0], S[k, g, 1], S[k, g, 2]
                szz = -(sxx + syy)
                # Jaumann: dS/dt = 2G D' + W S - S W, W = [[0, w], [-w, 0]] in the plane
                nxx = sxx + dt * (2 * shear * dxx + 2 * w_spin * sxy)
                nyy = syy + dt * (2 * shear * dyy - 2 * w_spin * sxy)
                nxy = sxy + dt * (2 * shear * dxy + w_spin * (syy - sxx))
                nzz = szz + dt * 2 * shear * dzz
                mean = (nxx + nyy + nzz) / 3.0  # round-off only
                S33[0, 0], S33[1, 1], S33[2, 2] = nxx - mean, nyy - mean, nzz - mean
                S33[0, 1] = S33[1, 0] = nxy
                local[EQUIVALENT_PLASTIC_STRAIN] = state[k, g, 0]
                local[PLASTIC_STRAIN_RATE] = state[k, g, 1]
                local[TEMPERATURE] = state[k, g, 2]
                thermal = thermal_factor(local[TEMPERATURE], M[T_REF], M[T_MELT],
                                         M[THERMAL_M])
                wp = hardening_return(S33, rho_new, shear, local, dt, M[FLOW_A], M[FLOW_B],
                                      M[FLOW_N], M[FLOW_C], M[RATE0], thermal)
                plastic += wp * rho_new * w[g]
                state[k, g, 0] = local[EQUIVALENT_PLASTIC_STRAIN]
                state[k, g, 1] = local[PLASTIC_STRAIN_RATE]
                state[k, g, 2] = local[TEMPERATURE] + M[HEAT_PER_WORK] * wp
                nxx, nyy, nzz, nxy = S33[0, 0], S33[1, 1], S33[2, 2], S33[0, 1]
                # the deviatoric power with the mean of the old and new stresses
                power[g] = 0.5 * ((sxx + nxx) * dxx + (syy + nyy) * dyy + (szz + nzz) * dzz
                                  + 2 * (sxy + nxy) * dxy) * w[g]
                S[k, g, 0], S[k, g, 1], S[k, g, 2] = nxx, nyy, nxy
            div /= volume
            deviatoric_power = power[0] + power[1] + power[2] + power[3]
            rho_old = rho[k]
            c = math.sqrt(max((M[A0] + 4.0 / 3.0 * shear) / rho_new, 1.0))
            q = 0.0
            if div < 0.0:  # bulk viscosity on the mean volumetric rate, compression only
                q = rho_new * (Q_QUADRATIC * length * length * div * div
                               - Q_LINEAR * c * length * div)
            # e1 = e0 + [-(p0 + p1)/2 - q] d(1/rho) + W_dev / m, p1 = A(rho1) + Gamma rho1 e1
            dspec = 1.0 / rho_new - 1.0 / rho_old
            cold = mie_gruneisen_pressure(rho_new, 0.0, M[RHO0], M[A0], M[B0], M[C0],
                                          M[GRUNEISEN])
            rhs = (e[k] + (-0.5 * (p[k] + cold) - q) * dspec
                   + dt * deviatoric_power / mass_e[k])
            e[k] = rhs / (1.0 + 0.5 * M[GRUNEISEN] * rho_new * dspec)
            p[k] = cold + M[GRUNEISEN] * rho_new * e[k]
            rho[k] = rho_new
            p_total = p[k] + q
        else:
            c = math.sqrt((M[A0] + 4.0 / 3.0 * shear) / rho[k])
            p_total = p[k]
        dt_min = min(dt_min, COURANT * length / c)
        for g in range(4):
            sxx = S[k, g, 0] - p_total
            syy = S[k, g, 1] - p_total
            sxy = S[k, g, 2]
            szz = -(S[k, g, 0] + S[k, g, 1]) - p_total
            for a in range(4):
                n = nodes[a]
                fx = sxx * dN[g, a, 0] + sxy * dN[g, a, 1]
                if axisymmetric:
                    fx += szz * SHAPE[g, a] / radius[g]
                force[n, 0] -= fx * w[g]
                force[n, 1] -= (sxy * dN[g, a, 0] + syy * dN[g, a, 1]) * w[g]
    return force, dt_min, plastic


def run(bar: Bar, n_across: int) -> dict:
    """The half bar with ``n_across`` elements over its half-width, to ``bar.end``."""
    x, elements = mesh(bar, n_across)
    M = bar.material
    n_el = elements.shape[0]
    mass, mass_e = lumped_masses(x, elements, M[RHO0], bar.axisymmetric)
    v = np.zeros_like(x)
    v[:, 1] = -bar.speed
    rho, e, p = np.full(n_el, M[RHO0]), np.zeros(n_el), np.zeros(n_el)
    S = np.zeros((n_el, 4, 3))
    state = np.zeros((n_el, 4, 3))  # equivalent plastic strain, its rate, temperature
    state[:, :, 2] = M[T_INITIAL]
    on_axis = x[:, 0] == 0.0
    ke0 = 0.5 * float(np.sum(mass * (v * v).sum(1)))
    # the bottom row stops dead in the first step (a kinematic contact): its kinetic energy
    # is lost (a node that lands later, as a lifted rim that touches again, loses its normal
    # velocity too: that is inside the energy error reported)
    impact_loss = 0.5 * float(np.sum(mass[x[:, 1] == 0.0])) * bar.speed**2 / ke0
    force, dt, _ = element_pass(x, v, elements, mass_e, rho, e, S, state, p, 0.0, M,
                                bar.axisymmetric, False)
    t, steps, plastic = 0.0, 0, 0.0
    pending = sorted(bar.snapshots)
    # the half section -> the whole bar (plane strain); per radian as it is (axisymmetry, as
    # the SPH run's energies)
    whole = 1.0 if bar.axisymmetric else 2.0
    out: dict = {"bar": bar.name, "axisymmetric": bar.axisymmetric, "n_across": n_across,
                 "elements": int(n_el), "nodes": int(len(x)), "snapshots": {}}
    start = time.perf_counter()
    while t < bar.end * (1 - 1e-12):
        dt = min(dt, bar.end - t, *(s - t for s in pending if s > t * (1 + 1e-12)))
        v += dt * force / mass[:, None]
        v[on_axis, 0] = 0.0
        # the wall: a node that would cross it lands on it (its velocity is what takes it
        # there), so the strain rates see the same motion as the positions
        below = x[:, 1] + dt * v[:, 1] < 0.0
        if np.any(below):
            v[below, 1] = -x[below, 1] / dt
        x += dt * v
        x[below, 1] = 0.0  # round-off
        force, dt_next, dw = element_pass(x, v, elements, mass_e, rho, e, S, state, p, dt,
                                          M, bar.axisymmetric, True)
        plastic += dw
        t += dt
        steps += 1
        dt = dt_next
        if not np.all(np.isfinite(x)) or np.any(rho <= 0):
            raise RuntimeError(f"non-finite state at t = {t:.3e} s, step {steps}")
        while pending and t >= pending[0] * (1 - 1e-12):
            pending.pop(0)
            contact = x[:, 1] <= 1e-12
            ke = 0.5 * float(np.sum(mass * (v * v).sum(1)))
            ie = float(np.sum(mass_e * e))  # e includes the elastic and the dissipated energy
            out["snapshots"][f"{t * 1e6:g}us"] = {
                "final_length_ratio": float((x[:, 1].max() - x[:, 1].min()) / bar.length),
                "lift_off": float(x[:, 1].min()),  # m: the lowest node's height
                "footprint_half_width_ratio": (float(x[contact, 0].max() / bar.half_width)
                                               if np.any(contact) else 0.0),
                "footprint_half_width_ratio_fixed": footprint_within(
                    boundary(x, n_across), FOOT_LIFT * bar.half_width) / bar.half_width,
                "corner": [float(c) for c in x[n_across] / bar.half_width],  # the foot's rim
                "widest_section_ratio": float(x[:, 0].max() / bar.half_width),
                "plastic_work": whole * plastic,
                "kinetic_energy_ratio": ke / ke0,
                "energy_error": (ke + ie - ke0) / ke0 + impact_loss,
                "first_impact_loss": impact_loss,
                "max_equivalent_plastic_strain": float(state[:, :, 0].max()),
                "max_temperature": float(state[:, :, 2].max()),
            }
    out["steps"] = steps
    out["wall_seconds"] = time.perf_counter() - start
    out["boundary_final"] = boundary(x, n_across).tolist()
    return out


def footprint_within(outline: np.ndarray, lift: float) -> float:
    """The outermost point (largest x) of the ``outline`` (points ``(x, y)`` in order, the wall
    at ``y = 0``) within ``lift`` of the wall or, once the bar has left it, of its lowest
    point (as the SPH measure's fixed band); where an edge crosses that height, the crossing
    itself."""
    x, y = outline[:, 0], outline[:, 1]
    level = max(0.0, float(y.min())) + lift
    best = float(x[y <= level].max())
    x1, y1, x2, y2 = x[:-1], y[:-1], x[1:], y[1:]
    cross = (y1 - level) * (y2 - level) < 0.0
    if cross.any():
        at = x1[cross] + (level - y1[cross]) / (y2[cross] - y1[cross]) * (x2[cross] - x1[cross])
        best = max(best, float(at.max()))
    return best


def boundary(x: np.ndarray, n_across: int) -> np.ndarray:
    """The outline of the half bar, counter-clockwise from the axis at the wall."""
    grid = x.reshape(-1, n_across + 1, 2)
    return np.concatenate([grid[0], grid[1:, -1], grid[-1, ::-1][1:], grid[::-1, 0][1:]])


def figure(results: list[dict], bar: Bar, path: Path, sph: list[Path] = ()) -> Path:
    """The final outlines of the half bar at each resolution (mm), over the particles of the
    SPH runs ``sph`` at the same time (their x >= 0 half; a run of the same case)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from impactsph.output import load_run

    fig, ax = plt.subplots(figsize=(5, 6))
    for k, run_dir in enumerate(sph):
        snaps = load_run(run_dir)["snapshots"]
        snap = min(snaps, key=lambda s: abs(s["time"] - bar.end))
        x = snap["position"]
        half = x[:, 0] >= 0.0
        ax.scatter(1e3 * x[half, 0], 1e3 * x[half, 1], s=2 if len(x) > 5000 else 5,
                   color=f"C{k + 1}", alpha=0.6, label=f"SPH {run_dir.name} ({len(x)})")
    for result, style in zip(results, ["k:", "k--", "k-.", "k-", "k-"], strict=False):
        outline = 1e3 * np.array(result["boundary_final"])
        ax.plot(outline[:, 0], outline[:, 1], style, lw=1.0,
                label=f"FE, {result['n_across']} across")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)" if not bar.axisymmetric else "r (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{bar.name} at {bar.end * 1e6:g} us")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("n_across", type=positive_int, nargs="+",
                        help="elements across the half-width")
    parser.add_argument("--test", default=None, metavar="MATERIAL:VELOCITY",
                        help="a test of validation/taylor_measured.toml in axisymmetry, e.g. "
                             "ofhc_copper:190 (default: the paper's plane-strain bar)")
    parser.add_argument("--case", default="taylor", choices=["taylor", "taylor_axisymmetric"],
                        help="the paper's bar: plane strain (default) or the cylinder in "
                             "axisymmetry")
    parser.add_argument("--out", type=Path, default=Path("runs/validation/taylor-fem"))
    parser.add_argument("--sph", type=Path, nargs="*", default=[],
                        help="SPH run directories of the same case to draw under the outlines")
    args = parser.parse_args()
    if args.test:
        material, velocity = args.test.split(":")
        bar = measured_bar(material, float(velocity))
    else:
        bar = paper_bar(args.case)
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for n in args.n_across:
        result = run(bar, n)
        results.append(result)
        write_study(args.out / f"{bar.name}-{n}.json", result)
        last = result["snapshots"][f"{bar.end * 1e6:g}us"]
        print(f"{bar.name}, {n} across ({result['elements']} elements, {result['steps']} "
              f"steps, {result['wall_seconds']:.1f} s): " + ", ".join(
                  f"{t}: L {s['final_length_ratio']:.4f} foot "
                  f"{s['footprint_half_width_ratio']:.3f} widest {s['widest_section_ratio']:.3f}"
                  for t, s in result["snapshots"].items())
              + f"; plastic work {last['plastic_work']:.4g}, energy error "
                f"{last['energy_error']:.2e} (net of the bottom row's first impact, "
                f"{last['first_impact_loss']:.2e}); max eps_p "
                f"{last['max_equivalent_plastic_strain']:.3f}, T {last['max_temperature']:.0f} K",
              flush=True)
    print(f"figure: {figure(results, bar, args.out / f'{bar.name}-outlines.png', args.sph)}")


if __name__ == "__main__":
    main()
