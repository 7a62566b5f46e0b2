"""The compiled pair loop against a plain reference built from the term functions.

``physics/rates.py`` applies every term in one loop over packed, cell-ordered particle
records, with the stress terms regrouped (``A_i`` applied once per particle).  Here the same
rates are summed pair by pair, over all particles (no neighbour list), by calling the
per-term functions of ``physics/*`` exactly as their docstrings state the equations.  Two
bodies in contact, random velocities, densities and stresses, in 1D, 2D and 3D, with AV and
with AC: the two must agree to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest
from fields import random_deviator

from impactsph.kernels import cubic_spline_dwdr
from impactsph.loading import validate_case
from impactsph.materials import SHEAR, WAVE_MODULUS
from impactsph.models.viscosity.correction import (
    ENERGY_CORRECTIONS,
    VARIANTS,
    corrected_viscous_acceleration,
    correction_weight,
)
from impactsph.models.viscosity.monaghan import monaghan_viscosity
from impactsph.physics.contact import (
    contact_acceleration_pair,
    contact_work_pair,
    in_contact,
)
from impactsph.physics.continuity import continuity_pair, velocity_gradient_pair
from impactsph.physics.energy import stress_work_pair, viscous_heating_pair
from impactsph.physics.momentum import stress_acceleration_pair, viscous_acceleration_pair
from impactsph.physics.rates import pressures
from impactsph.physics.stress_rate import symmetric_full
from impactsph.simulation import Simulation

DX = 1e-3


def two_blocks(dim: int, scheme: str) -> Simulation:
    """Two steel blocks a little closer than one spacing, approaching, perturbed."""
    side = {1: 12, 2: 6, 3: 4}[dim]
    size = [side * DX] * dim
    shifted = [0.0] * dim
    shifted[0] = side * DX * 0.97
    case = validate_case({
        "name": f"ref{dim}", "dimension": dim,
        "materials": {"steel": {"model": "elastic", "density": 7850.0, "youngs_modulus": 2e11,
                                "poisson_ratio": 0.3,
                                "eos": "linear" if dim != 2 else "mie_gruneisen",
                                **({"mie_gruneisen": {"sound_speed": 4600.0, "slope": 1.5,
                                                      "gamma": 2.0}} if dim == 2 else {})}},
        "bodies": [
            {"name": "a", "material": "steel", "velocity": [30.0] + [0.0] * (dim - 1),
             "geometry": {"origin": [0.0] * dim, "size": size, "spacing": DX}},
            {"name": "b", "material": "steel", "velocity": [-30.0] + [0.0] * (dim - 1),
             "geometry": {"origin": shifted, "size": size, "spacing": DX}},
        ],
        "kernel": {"h_over_dx": 1.3}, "viscosity": {"scheme": scheme},
        # the reference restates the plain terms and the pressure contact (docs/modelling.md)
        "stabilisation": {"gradient_correction": "none", "hourglass": 0.0},
        "contact": {"traction": "pressure"},
        "time": {"end": 1e-6}, "output": {"figures": False},
    })
    sim = Simulation(case)
    s = sim.state
    rng = np.random.default_rng(dim)
    s.position += rng.normal(0.0, 0.05 * DX, s.position.shape)
    s.velocity += rng.normal(0.0, 20.0, s.velocity.shape)
    s.density *= 1.0 + rng.normal(0.0, 2e-3, s.n)
    s.specific_energy[:] = rng.uniform(0.0, 1e3, s.n)
    s.deviatoric_stress[:] = random_deviator(rng, s.n, dim, 2e8)
    s.smoothing_length *= 1.0 + rng.uniform(-0.05, 0.05, s.n)  # unequal h: the general branch
    return sim


def reference_rates(sim: Simulation):
    """``dv, drho, de, dS`` and the AC terms, pair by pair from the term functions."""
    s, table, visc = sim.state, sim.problem.table, sim.case.viscosity
    n, dim = s.n, s.dim
    x, v, rho, m, h, body = (s.position, s.velocity, s.density, s.mass, s.smoothing_length,
                             s.body)
    p = pressures(rho, s.specific_energy, s.material, table, dim)
    c = np.sqrt(table[s.material, WAVE_MODULUS] / rho)
    A = s.deviatoric_stress[:, :dim, :dim] / rho[:, None, None] ** 2
    A -= (p / rho**2)[:, None, None] * np.eye(dim)
    pc = p / rho**2
    alpha = (1.0, 1.0) if visc.scheme == "ac" else (visc.alpha1, visc.alpha2)
    drho, de = np.zeros(n), np.zeros(n)
    dv, u = np.zeros((n, dim)), np.zeros((n, dim))
    dS = np.zeros((n, 3, 3))
    for i in range(n):
        L = np.zeros((dim, dim))
        for j in range(n):
            r_ij = x[i] - x[j]
            r = float(np.linalg.norm(r_ij))
            h_ij = 0.5 * (h[i] + h[j])
            if j == i or r >= 2.0 * h_ij:
                continue
            g = cubic_spline_dwdr(r, h_ij, dim) / r * r_ij
            v_ij = v[i] - v[j]
            vg = float(v_ij @ g)
            V_j = m[j] / rho[j]
            if body[i] == body[j]:
                drho[i] += continuity_pair(rho[i], V_j, vg)
                for a in range(dim):
                    dv[i, a] += stress_acceleration_pair(m[j], A[i], A[j], g, a, dim)
                    for b in range(dim):
                        L[a, b] += velocity_gradient_pair(V_j, v_ij[a], g[b])
                de[i] += stress_work_pair(m[j], A[i], v_ij, g, dim)
            else:
                s_ij = pc[i] + pc[j]
                if in_contact(s_ij, vg):
                    drho[i] += continuity_pair(rho[i], V_j, vg)
                    for a in range(dim):
                        dv[i, a] += contact_acceleration_pair(m[j], s_ij, g[a])
                    de[i] += contact_work_pair(m[j], pc[i], s_ij, vg)
            pi_ij = monaghan_viscosity(float(v_ij @ r_ij), r * r, h_ij, 0.5 * (c[i] + c[j]),
                                       0.5 * (rho[i] + rho[j]), *alpha, visc.epsilon)
            for a in range(dim):
                u[i, a] += viscous_acceleration_pair(m[j], pi_ij, g[a])
            de[i] += viscous_heating_pair(m[j], pi_ij, vg)
        # eq 14 in matrix form, 3x3 (the passes write its six components)
        L3 = np.zeros((3, 3))
        L3[:dim, :dim] = L
        strain_rate, spin = 0.5 * (L3 + L3.T), 0.5 * (L3 - L3.T)
        S_i = s.deviatoric_stress[i]
        dS[i] = (2.0 * table[s.material[i], SHEAR] * (strain_rate - np.trace(L3) / 3.0 * np.eye(3))
                 + spin @ S_i - S_i @ spin)
    dv += u
    dv_corr, de_corr = np.zeros((n, dim)), np.zeros(n)
    if visc.scheme == "ac":
        variant = VARIANTS[visc.correction]
        assert ENERGY_CORRECTIONS[visc.energy_correction] == ENERGY_CORRECTIONS["work"]
        for i in range(n):
            hc_i = visc.correction_h_ratio * h[i]
            self_weight = correction_weight(m[i] / rho[i], 0.0, hc_i, dim)
            weight_sum, weighted = 0.0, np.zeros(dim)
            for j in range(n):
                h_c = visc.correction_h_ratio * 0.5 * (h[i] + h[j])
                r = float(np.linalg.norm(x[i] - x[j]))
                if j == i or body[j] != body[i] or r >= 2.0 * h_c:
                    continue
                w = correction_weight(m[j] / rho[j], r, h_c, dim)
                weight_sum += w
                weighted += w * u[j]
            for a in range(dim):
                dv_corr[i, a] = corrected_viscous_acceleration(
                    u[i, a], self_weight, weight_sum, weighted[a], variant) - u[i, a]
            de_corr[i] = -float(v[i] @ dv_corr[i])
    return dv + dv_corr, drho, de + de_corr, dS


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("scheme", ["av", "ac"])
def test_pair_loop_equals_term_by_term_reference(dim, scheme):
    sim = two_blocks(dim, scheme)
    got = [np.array(a[: sim.state.n]) for a in sim.solver.rates(sim.state)[:4]]
    got[3] = symmetric_full(got[3])  # the rate's six components, as a 3x3 tensor
    want = reference_rates(sim)
    assert sim.solver.buffers.contact_force.shape[0] > 0  # two bodies: contact is on
    for name, g, w in zip(("dv", "drho", "de", "dS"), got, want, strict=True):
        scale = np.abs(w).max()
        assert scale > 0, name
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-11 * scale, err_msg=name)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("scheme", ["av", "ac"])
def test_a_list_split_before_the_particles_moved_gives_the_same_rates(dim, scheme):
    """A 2D or 3D list's rows hold the pairs within their support at the build first, which the
    passes take untested, and test only the rest (``NeighbourList.splits``).  Once the
    particles have moved, within half the skin (the list is not rebuilt), some pairs of the
    front part have left the support and some of the back part have entered it: the rates
    still equal the reference's at the new positions."""
    sim = two_blocks(dim, scheme)
    sim.solver.rates(sim.state)  # the list at these positions
    nl = sim.solver.neighbours
    builds = nl.builds
    rng = np.random.default_rng(5)
    direction = rng.normal(size=sim.state.position.shape)
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    sim.state.position += 0.45 * nl.skin * direction
    got = [np.array(a[: sim.state.n]) for a in sim.solver.rates(sim.state)[:4]]
    assert sim.solver.neighbours is nl and nl.builds == builds  # the same list, not rebuilt
    # pairs that crossed the support since the build, out of each part of the rows
    xs = sim.state.position[nl.order]
    hs = sim.state.smoothing_length[nl.order]
    rows = np.repeat(np.arange(nl.order.shape[0]), np.diff(nl.offsets))
    inside = (np.linalg.norm(xs[rows] - xs[nl.indices], axis=1)
              < (hs[rows] + hs[nl.indices]))  # r < 2 h_ij
    front = np.arange(nl.indices.shape[0]) < np.repeat(nl.splits, np.diff(nl.offsets))
    assert np.count_nonzero(front & ~inside) > 0 and np.count_nonzero(~front & inside) > 0
    want = reference_rates(sim)
    # splits that are not the list's own (none: every row tested; every row taken untested;
    # outside the rows) cost time, never correctness (passes.support_range)
    splits = nl.splits
    others = [None, nl.offsets[1:].copy(), nl.offsets[:-1] - 5, nl.offsets[1:] + 5]
    for other in [splits, *others]:
        nl.splits = other
        if other is not splits:
            got = [np.array(a[: sim.state.n]) for a in sim.solver.rates(sim.state)[:4]]
        got[3] = symmetric_full(got[3])
        for name, g, w in zip(("dv", "drho", "de", "dS"), got, want, strict=True):
            np.testing.assert_allclose(g, w, rtol=0, atol=1e-11 * np.abs(w).max(),
                                       err_msg=name)
