"""The artificial stress against the tensile instability (``stabilisation.artificial_stress =
epsilon``; Monaghan 2000, Gray, Monaghan & Swift 2001; docs/stabilisation.md).

- The particle's ``R`` is ``-epsilon`` times the tensile part of ``sigma / rho^2`` (its
  positive eigenvalues on their eigenvectors), against ``numpy.linalg.eigh``.
- The pair terms against the equations summed pair by pair; momentum to round-off and the
  energy term matching the force's power, with and without the correction of the forces.
- The tension rod and the colliding rubber rings (``validation/artificial_stress.py``): with
  epsilon = 0.3 they stay whole where the plain scheme clumps and breaks; the rings rebound,
  keep momentum to round-off and energy to 1e-3.  The rod's front is 10% slower than the bar
  speed: the artificial stress softens the material in tension, which its long-wave analysis
  predicts to 0.5% (an expected failure below records the bound it misses).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from impactsph import Simulation
from impactsph.kernels import cubic_spline_dwdr
from impactsph.loading import validate_case
from impactsph.physics.options import PassOptions
from impactsph.physics.rates import compiled_passes, pressures
from impactsph.problem import build_problem

sys.path.insert(0, str(Path(__file__).parent.parent / "validation"))
import artificial_stress as validation  # noqa: E402

EPS = validation.EPSILON
H_OVER_DX = validation.H_OVER_DX
#: the options every test here compiles (one module per dimension, shared with the runs)
OPTIONS = PassOptions(artificial_stress=EPS, reference_q=1.0 / H_OVER_DX)


def tensile_part(a: np.ndarray) -> np.ndarray:
    """``sum_k max(lambda_k, 0) e_k (x) e_k`` by numpy."""
    w, v = np.linalg.eigh(a)
    return (v * np.maximum(w, 0.0)) @ v.T


def symmetric(t: tuple, dim: int) -> np.ndarray:
    """A symmetric matrix from its upper triangle, row by row."""
    out = np.zeros((dim, dim))
    out[np.triu_indices(dim)] = t
    return out + np.triu(out, 1).T


def random_symmetric(rng: np.random.Generator, dim: int, kind: int) -> np.ndarray:
    """General, repeated eigenvalues, nearly repeated, or entries over ten decades."""
    q, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    if kind == 0:
        a = rng.normal(size=(dim, dim))
    elif kind == 1:
        a = (q * rng.choice([-1.0, 0.0, 1.0, 2.0], dim)) @ q.T
    elif kind == 2:
        a = (q * (1.0 + np.array([0.0, 1e-9, -1.5][:dim]) * rng.normal(size=dim))) @ q.T
    else:
        a = rng.normal(size=(dim, dim)) * 10.0 ** rng.uniform(-5.0, 5.0, (dim, dim))
    return (a + a.T) * 10.0 ** rng.uniform(-3.0, 9.0)


# -- R of one particle -----------------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
def test_tensile_part_matches_eigh(dim):
    """The 2D decomposition (Gray et al.'s principal angle) and the 3D one (cyclic Jacobi
    sweeps on scalars) against numpy, general and degenerate tensors: to 1e-13 of the
    largest entry."""
    k = compiled_passes(dim, options=OPTIONS)
    part = k.tension_part_2d if dim == 2 else k.tension_part_3d
    rng = np.random.default_rng(dim)
    worst = 0.0
    for trial in range(4000):
        a = random_symmetric(rng, dim, trial % 4)
        got = symmetric(part(*a[np.triu_indices(dim)]), dim)
        scale = np.abs(a).max()
        if scale > 0:
            worst = max(worst, np.abs(got - tensile_part(a)).max() / scale)
    assert worst < 1e-13
    assert np.array_equal(symmetric(part(*np.zeros(dim * (dim + 1) // 2)), dim),
                          np.zeros((dim, dim)))


def block_problem(dim: int):
    case = validate_case({
        "name": "record", "dimension": dim,
        "materials": {"m": {"model": "elastic" if dim > 1 else "bar", "density": 1000.0,
                            "youngs_modulus": 1e7, "poisson_ratio": 0.3}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0] * dim,
                    "geometry": {"origin": [0.0] * dim, "size": [{1: 24, 2: 6, 3: 3}[dim]
                                                                * 1e-3] * dim,
                                 "spacing": 1e-3}}],
        "kernel": {"h_over_dx": H_OVER_DX}, "stabilisation": {"artificial_stress": EPS},
        "time": {"end": 1e-6}, "output": {"figures": False}})
    return build_problem(case)


def record_artificial_stress(problem, dim: int) -> np.ndarray:
    """Every particle's ``R`` as the particle pass writes it into the packed records."""
    k = compiled_passes(dim, options=OPTIONS)
    s, n = problem.state, problem.state.n
    P = np.zeros((n, k.RECORD_WIDTH))
    k.particle_pass(np.arange(n), s.position, s.velocity, s.mass, s.density,
                    s.specific_energy, s.deviatoric_stress, s.material_state[:, :5].copy(),
                    s.smoothing_length, s.body,
                    s.material, problem.table, P)
    upper = np.triu_indices(dim)
    return np.stack([symmetric(P[p, k.RS0: k.RS0 + len(upper[0])], dim) for p in range(n)])


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_record_holds_minus_epsilon_times_the_tensile_stress(dim):
    """Random densities (pressure of either sign) and deviators: the record's ``R`` is
    ``-epsilon`` times the tensile part of ``sigma = -P I + S`` (its in-plane part in plane
    strain) over ``rho^2``, to 1e-10 of its largest entry."""
    problem = block_problem(dim)
    s = problem.state
    rng = np.random.default_rng(10 + dim)
    s.density *= 1.0 + rng.normal(0.0, 0.02, s.n)
    S = rng.normal(0.0, 2e5, (s.n, 3, 3))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    S -= np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    if dim == 2:
        S[:, 2, :2] = S[:, :2, 2] = 0.0
    s.deviatoric_stress[:] = S
    R = record_artificial_stress(problem, dim)
    p = pressures(s.density, s.specific_energy, s.material, problem.table, dim)
    sigma = S[:, :dim, :dim] - p[:, None, None] * np.eye(dim)
    want = np.stack([-EPS * tensile_part(sg) / r**2 for sg, r in zip(sigma, s.density,
                                                                       strict=True)])
    assert np.abs(want).max() > 0 and (want == 0).all(axis=(1, 2)).any()  # tension and none
    assert np.abs(R - want).max() < 1e-10 * np.abs(want).max()


def test_uniaxial_tension_along_a_rotated_axis():
    """Plane strain, ``sigma = T n (x) n`` along ``n`` at 30 degrees (``P = -T/3``, the
    deviator ``T (n (x) n - I/3)``): ``R = -epsilon T n (x) n / rho^2`` exactly; and
    compression along ``n`` gives none."""
    problem = block_problem(2)
    s, K = problem.state, problem.materials[0].bulk_modulus
    n = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0])
    for T in (3e5, -3e5):
        s.density[:] = 1000.0 * (1.0 - T / 3.0 / K)  # P = K (rho/rho0 - 1) = -T/3
        s.deviatoric_stress[:] = T * (np.outer(n, n) - np.eye(3) / 3.0)
        R = record_artificial_stress(problem, 2)
        want = -EPS * max(T, 0.0) * np.outer(n[:2], n[:2]) / s.density[:, None, None] ** 2
        assert np.abs(R - want).max() < 1e-10 * EPS * 3e5 / 1000.0**2


# -- the pair terms --------------------------------------------------------------------------


def stretched_block(epsilon: float, correction: str, compensation: bool = False
                    ) -> Simulation:
    """A jittered 2D block in tension (expanding, below its reference density, random
    deviators) with random velocities on top (``compensation``:
    ``stabilisation.artificial_stress_compensation``)."""
    case = validate_case({
        "name": "as", "dimension": 2,
        "materials": {"m": {"model": "elastic", "density": 1000.0, "youngs_modulus": 1e7}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0],
                    "geometry": {"origin": [0.0, 0.0], "size": [8e-3, 8e-3],
                                 "spacing": 1e-3}}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "stabilisation": {"gradient_correction": correction, "artificial_stress": epsilon,
                          **({"artificial_stress_compensation": True} if compensation
                             else {})},
        "time": {"end": 1e-6}, "output": {"figures": False}})
    sim = Simulation(case)
    _disturb(sim.state, 1, np.zeros(2))
    return sim


def _disturb(s, seed: int, centre: np.ndarray) -> None:
    """Jiggled positions, a stretching velocity about ``centre`` with noise, densities a few
    per cent low and a random in-plane deviatoric stress (principal stresses of both signs)."""
    rng = np.random.default_rng(seed)
    s.position += rng.uniform(-0.15, 0.15, s.position.shape) * 1e-3
    s.velocity[:] = 20.0 * (s.position - centre) + rng.normal(0.0, 0.5, s.velocity.shape)
    s.density *= 1.0 - rng.uniform(0.0, 0.03, s.n)
    S = rng.normal(0.0, 1e5, (s.n, 3, 3))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    S -= np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    S[:, 2, :2] = S[:, :2, 2] = 0.0
    s.deviatoric_stress[:] = S


def pair_sums(sim: Simulation, R: np.ndarray, own: np.ndarray, neighbour: np.ndarray,
              kappa: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``dv_i = sum_j (f_ij^n - kappa) (own_ij R_i + neighbour_ij R_j) . grad W_ij`` and
    ``de_i = -1/2 sum_j v_ij . (the same)``, pair by pair (AS-2 to AS-4 of
    :mod:`impactsph.physics.passes`), with the weights ``own[i, j]`` and ``neighbour[i, j]``."""
    s = sim.state
    x, v, h = s.position, s.velocity, s.smoothing_length

    def shape(q: float) -> float:
        return 1 - 1.5 * q**2 + 0.75 * q**3 if q <= 1 else 0.25 * (2 - q) ** 3

    dv, de = np.zeros((s.n, 2)), np.zeros(s.n)
    for i in range(s.n):
        for j in range(s.n):
            r_ij = x[i] - x[j]
            r = float(np.linalg.norm(r_ij))
            h_ij = 0.5 * (h[i] + h[j])
            if j == i or r >= 2.0 * h_ij:
                continue
            g = cubic_spline_dwdr(r, h_ij, 2) / r * r_ij
            fn = (shape(r / h_ij) / shape(1.0 / H_OVER_DX)) ** 4 - kappa
            push = fn * (own[i, j] * R[i] + neighbour[i, j] * R[j]) @ g
            dv[i] += push
            de[i] -= 0.5 * (v[i] - v[j]) @ push
    return dv, de


def stress_in_plane(sim: Simulation) -> np.ndarray:
    """``sigma = -P I + S`` of each particle, its in-plane 2x2 part (Pa)."""
    s = sim.state
    p = pressures(s.material_density, s.specific_energy, s.material, sim.problem.table, 2)
    return s.deviatoric_stress[:, :2, :2] - p[:, None, None] * np.eye(2)


def reference_terms(sim: Simulation, kappa: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``dv`` and ``de`` of the artificial stress alone in plane strain: :func:`pair_sums`
    with ``R = -epsilon tensile(sigma) / rho^2`` and the weight ``m_j`` on both (with the
    compensation, ``f^n - kappa``)."""
    s = sim.state
    R = np.stack([-EPS * tensile_part(sg) / r**2
                  for sg, r in zip(stress_in_plane(sim), s.density, strict=True)])
    m = np.broadcast_to(s.mass, (s.n, s.n))
    return pair_sums(sim, R, m, m, kappa)


@pytest.mark.parametrize("correction,compensation", [
    ("none", False), ("velocity_gradient_and_forces", False), ("none", True)])
def test_pair_terms_conserve_momentum_and_energy(correction, compensation):
    """The rates with epsilon = 0.3 less those without: the artificial stress's own terms.
    They are the pair sums of AS-3 and AS-4 (on the uncorrected kernel gradient, also with
    the correction of the forces; with the compensation, the weight ``f^n - kappa``), to
    1e-10; their total force is zero to round-off and their power on the velocities is
    taken from the internal energy to round-off."""
    on = stretched_block(EPS, correction, compensation)
    off = stretched_block(0.0, correction)
    s = on.state
    dv_on, _, de_on, _, _ = (np.array(r[: s.n]) for r in on.solver.rates(s))
    dv_off, _, de_off, _, _ = (np.array(r[: s.n]) for r in off.solver.rates(off.state))
    dv, de = dv_on - dv_off, de_on - de_off
    kappa = PassOptions.of_case(on.case).compensation(2)
    assert (kappa > 0.4) == compensation
    dv_ref, de_ref = reference_terms(on, kappa)
    assert np.abs(dv_ref).max() > 0.05 * np.abs(dv_off).max()  # not a negligible term
    assert np.abs(dv - dv_ref).max() < 1e-10 * np.abs(dv_ref).max()
    assert np.abs(de - de_ref).max() < 1e-10 * np.abs(de_ref).max()
    m, v = s.mass, s.velocity
    force_scale = float(np.sum(m[:, None] * np.abs(dv)))
    power_scale = float(np.sum(np.abs(m * np.einsum("ia,ia->i", v, dv))))
    assert np.abs(m @ dv).max() < 1e-13 * force_scale
    assert abs(m @ np.einsum("ia,ia->i", v, dv) + m @ de) < 1e-13 * power_scale
    # and the whole scheme with it: momentum and energy of the total rates
    assert np.abs(m @ dv_on).max() < 1e-13 * float(np.sum(m[:, None] * np.abs(dv_on)))
    power = m * np.einsum("ia,ia->i", v, dv_on)
    assert abs(power.sum() + m @ de_on) < 1e-13 * float(np.abs(power).sum())


def stretched_ring(epsilon: float) -> Simulation:
    """:func:`stretched_block` in axisymmetry: the block a ring of rectangular section, from
    r = 4 mm (beyond the reach of the axis's ghosts), in tension with random velocities."""
    case = validate_case({
        "name": "as_axi", "dimension": 2, "two_dimensional": "axisymmetric",
        "materials": {"m": {"model": "elastic", "density": 1000.0, "youngs_modulus": 1e7}},
        "bodies": [{"name": "b", "material": "m", "velocity": [0.0, 0.0],
                    "geometry": {"origin": [4e-3, 0.0], "size": [8e-3, 8e-3],
                                 "spacing": 1e-3}}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "stabilisation": {"artificial_stress": epsilon},
        "time": {"end": 1e-6}, "output": {"figures": False}})
    sim = Simulation(case)
    _disturb(sim.state, 2, np.array([8e-3, 4e-3]))
    return sim


def test_pair_terms_in_axisymmetry_conserve_axial_momentum_and_energy():
    """Axisymmetry (``rho`` the mass per radian and area, ``A = |r| sigma / rho``): the
    artificial stress's own terms are the pair sums ``dv_i = sum_j f^n (V_j R_i + m_j R_j /
    rho_i) . grad W_ij`` and ``de_i = -1/2 sum_j f^n v_ij . (V_j R_i + m_j R_j / rho_i) . grad
    W_ij`` with ``R = -epsilon |r| tensile(sigma) / rho`` (the stress term's form), to 1e-10;
    their axial force is zero and their power is taken from the internal energy, to
    round-off; the whole scheme's total energy rate (hoop terms included) is zero."""
    on, off = stretched_ring(EPS), stretched_ring(0.0)
    s = on.state
    dv_on, _, de_on, _, _ = (np.array(r[: s.n]) for r in on.solver.rates(s))
    dv_off, _, de_off, _, _ = (np.array(r[: s.n]) for r in off.solver.rates(off.state))
    dv, de = dv_on - dv_off, de_on - de_off
    x, v, m, rho = s.position, s.velocity, s.mass, s.density
    R = np.stack([-EPS * abs(xi[0]) * tensile_part(sg) / r
                  for xi, sg, r in zip(x, stress_in_plane(on), rho, strict=True)])
    # own R_i weighted by V_j = m_j / rho_j, the neighbour's R_j by m_j / rho_i
    dv_ref, de_ref = pair_sums(on, R, np.broadcast_to(m / rho, (s.n, s.n)),
                               m[None, :] / rho[:, None])
    assert np.abs(dv_ref).max() > 0.05 * np.abs(dv_off).max()  # not a negligible term
    assert np.abs(dv - dv_ref).max() < 1e-10 * np.abs(dv_ref).max()
    assert np.abs(de - de_ref).max() < 1e-10 * np.abs(de_ref).max()
    force_scale = float(np.sum(m * np.abs(dv[:, 1])))
    power = m * np.einsum("ia,ia->i", v, dv)
    assert abs(m @ dv[:, 1]) < 1e-13 * force_scale
    assert abs(power.sum() + m @ de) < 1e-13 * float(np.abs(power).sum())
    power_on = m * np.einsum("ia,ia->i", v, dv_on)
    assert abs(power_on.sum() + m @ de_on) < 1e-13 * float(np.abs(power_on).sum())


# -- the tension rod -------------------------------------------------------------------------


def test_rod_in_axisymmetry_stays_regular():
    """The rod as a cylinder along the axis (``validation/artificial_stress.py rod-axi``):
    without the artificial stress its particles clump as the spacing falls (closest pair
    0.70 dx at 1 mm, 0.40 dx at 0.5 mm); with epsilon = 0.3 they stay a lattice (0.99 dx at
    both) and whole."""
    plain = validation.measure_axisymmetric_rod(5e-4, 0.0)
    assert plain["min_distance_over_dx"] < 0.5
    for spacing in (1e-3, 5e-4):
        run = validation.measure_axisymmetric_rod(spacing, EPS)
        assert run["failure"] is None
        assert run["min_distance_over_dx"] > 0.9, spacing
        assert run["max_separation_over_h"] < 1.5, spacing
        assert run["total_energy_relative_error"] < 1e-3


@pytest.fixture(scope="module")
def rods():
    """The rod in 1D at three spacings and in 2D at two, with epsilon = 0.3."""
    runs = {(1, dx): validation.measure_rod(1, dx, EPS) for dx in (1e-3, 5e-4, 2.5e-4)}
    runs.update({(2, dx): validation.measure_rod(2, dx, EPS) for dx in (1e-3, 5e-4)})
    return runs


def test_rod_stays_whole(rods):
    """No initial neighbours farther apart than 2.5 h, no two particles closer than 0.3 dx.
    (Without the artificial stress the 1D rod at dx = 0.25 mm breaks: 3.9 h, 0.24 dx;
    the 2D rod at 0.5 mm clumps to 0.32 dx: ``validation/artificial_stress.py rod``.)"""
    for key, run in rods.items():
        assert run["failure"] is None, key
        assert run["max_separation_over_h"] < 2.5, key
        assert run["min_distance_over_dx"] > 0.3, key


def test_rod_front_speed_is_the_discrete_long_wave_speed(rods):
    """The 1D front travels at the discrete long-wave speed in tension, ``c sqrt(M (M -
    epsilon M_f))`` = 0.899 c (``validation.lattice_moments``), within 1% of c at every
    spacing, closer as the spacing falls (measured -0.55%, -0.16%, +0.08%)."""
    errors = [abs(rods[(1, dx)]["error_vs_discrete"]) for dx in (1e-3, 5e-4, 2.5e-4)]
    assert max(errors) < 0.01
    assert errors[2] <= errors[0]


@pytest.mark.xfail(strict=True, reason="the artificial stress softens the material in "
                   "tension by epsilon M_f / M: the 1D front is 10.6%, 10.2%, 10.0% slower "
                   "than c at dx = 1, 0.5, 0.25 mm (2D, 8 mm wide: 12.3%, 9.0%); "
                   "docs/stabilisation.md (stabilisation.artificial_stress_compensation "
                   "removes the 1D part: test_compensated_rod_keeps_the_bar_speed)")
def test_rod_front_speed_is_the_bar_speed(rods):
    """Issue 11's bound for the tension rod: the front at the bar speed ``c = sqrt(E/rho)``
    within 3%, at two resolutions in 1D and 2D."""
    for key in ((1, 1e-3), (1, 5e-4), (2, 1e-3), (2, 5e-4)):
        assert abs(rods[key]["error_vs_c"]) < 0.03, key


def test_rod_front_speed_error_falls_in_2d(rods):
    """In 2D the narrow rod's free surfaces slow the front too; that part falls as the
    spacing falls (measured -12.3% at 1 mm, -9.0% at 0.5 mm)."""
    coarse, fine = rods[(2, 1e-3)]["error_vs_c"], rods[(2, 5e-4)]["error_vs_c"]
    assert abs(fine) < abs(coarse)


def test_compensated_rod_keeps_the_bar_speed():
    """With ``stabilisation.artificial_stress_compensation`` AS-3's weight is ``f^n - kappa``
    (kappa = M_f / M = 0.753 in 1D at h = 1.3 dx), which cancels the artificial stress's
    smooth part: the 1D rod's front runs at the plain scheme's long-wave speed ``M c`` (M =
    1.022) instead of 0.899 c, within 3% of c at 1, 0.5 and 0.25 mm (measured +1.3%, +1.7%,
    +2.0%, approaching M c from below as the front sharpens), and the rod stays whole as
    with the uncompensated form (initial neighbours within 0.81 h, none closer than 0.99
    dx)."""
    for dx in (1e-3, 5e-4, 2.5e-4):
        run = validation.measure_rod(1, dx, EPS, scheme="compensated")
        assert run["failure"] is None
        assert abs(run["error_vs_c"]) < 0.03, (dx, run["error_vs_c"])
        assert run["front_speed"] < 1.022 * validation.ROD_C * 1.005
        assert run["max_separation_over_h"] < 2.5 and run["min_distance_over_dx"] > 0.3


def test_compensation_constant():
    """kappa = M_f / M from the kernel on the lattice (1D 0.770 / 1.022; 2D 0.415 / 1.011),
    bound into the generated passes (its pair term: test_pair_terms_conserve_momentum_and_
    energy); a case asking for the compensation without the artificial stress is refused in
    one line."""
    on = PassOptions(artificial_stress=EPS, artificial_stress_compensation=True,
                     reference_q=1 / 1.3)
    assert on.compensation(1) == pytest.approx(0.7703 / 1.0224, rel=1e-3)
    assert on.compensation(2) == pytest.approx(0.4153 / 1.0105, rel=1e-3)
    assert PassOptions(artificial_stress=EPS).compensation(2) == 0.0
    assert f"AS_COMPENSATION = {on.compensation(2)!r}" in on.constants(2)
    assert on.tag != PassOptions(artificial_stress=EPS, reference_q=1 / 1.3).tag
    with pytest.raises(Exception, match="artificial_stress_compensation = true needs"):
        validate_case({
            "name": "refused", "dimension": 1,
            "materials": {"m": {"model": "bar", "density": 1000.0, "youngs_modulus": 1e7}},
            "bodies": [{"name": "b", "material": "m", "velocity": [0.0],
                        "geometry": {"origin": [0.0], "size": [0.01], "spacing": 1e-3}}],
            "stabilisation": {"artificial_stress_compensation": True},
            "time": {"end": 1e-6}})


# -- the rubber rings ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rings():
    return validation.measure_rings(2e-3, EPS, end=0.016)


def test_rubber_rings_rebound_whole(rings):
    """Gray et al.'s rings at 5 particles through the wall, 16 ms (they push on each other for
    the first 12 to 13 ms): they meet, rebound (the centres of mass move apart at the end: measured
    restitution 0.75), and stay whole (initial neighbours within 2.5 h, no two particles
    within 0.3 dx); momentum to round-off, total energy to 1e-3.  (Without the artificial
    stress they tear and clump: 5.2 h, 0.010 dx; docs/stabilisation.md.)"""
    assert rings["failure"] is None
    assert rings["slowest_approach"] < 0.5  # they met and slowed each other
    assert rings["velocity_left"] < 0.0 < rings["velocity_right"]
    distance = rings["centres_distance"]
    assert distance[-1] > distance[-2] > distance[-3]
    assert rings["max_separation_over_h"] < 2.5
    assert rings["min_distance_over_dx"] > 0.3
    assert rings["momentum_error"] < 1e-13
    assert rings["energy_error"] <= 1e-3


# -- the plane-strain Taylor bar's foot ----------------------------------------------------------


def _taylor_foot(epsilon: float) -> tuple[float, float]:
    """The paper's plane-strain Taylor bar (x1) with AV (1, 1) and the walls that hold, to 50
    us: the fraction of the region within 1 mm of the wall and 2.5 mm of the axis that its
    particles fill (count times the initial area per particle over the area), and L_f/L0."""
    from impactsph.loading import load_case
    from impactsph.problems.registry import analyse

    sim = Simulation(load_case("taylor", [
        'contact.traction="normal_stress"', "contact.wall_layer=0.25",
        'viscosity.scheme="av"', "viscosity.alpha1=1.0", "viscosity.alpha2=1.0",
        f"stabilisation.artificial_stress={epsilon}"]))
    sim.run()
    x, x0 = sim.state.position, sim.state.initial_position
    across = np.diff(np.unique(np.round(x0[:, 0], 9)))[0]
    along = np.diff(np.unique(np.round(x0[:, 1], 9)))[0]
    centre = x0[:, 0].mean()
    region = (x[:, 1] < 1e-3) & (np.abs(x[:, 0] - centre) < 2.5e-3)
    fill = float(region.sum() * across * along / (1e-3 * 5e-3))
    return fill, analyse("taylor", sim)["final_length_ratio"]


def test_the_taylor_foot_stays_filled():
    """The foot's tensile instability (docs/validation.md, "The plane-strain foot's holes"):
    without the artificial stress the particles under the axis pull apart into vertical chains
    with holes between them, and half of the region at the wall under the axis is empty
    (measured fill 0.52); with epsilon = 0.3 it is filled to 0.85 (0.93 at x2, 0.96 at x4,
    where the plain scheme's are 0.82 and 0.83).  The bar comes out 0.8% longer at x1 (0.8447
    against 0.8384)."""
    plain, plain_length = _taylor_foot(0.0)
    stressed, stressed_length = _taylor_foot(0.3)
    assert plain < 0.65
    assert stressed > 0.8
    assert 0 < stressed_length - plain_length < 0.015
