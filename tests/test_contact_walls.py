"""The contact traction and the walls' penalty layer (docs/stabilisation.md, "Walls that
hold"): the normal-stress contact against its pair formula and conservation; the layer's push,
its energy booking and that it only pushes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactsph.boundaries import LAYER_DAMPING, layer_push
from impactsph.kernels import cubic_spline_dwdr
from impactsph.loading import validate_case
from impactsph.materials import BULK, RHO0
from impactsph.simulation import Simulation

RHO, E, MU = 7850.0, 2.0e11, 8.0e10
DX = 1e-3


def two_blocks(traction: str, dim: int = 2) -> Simulation:
    """Two elastic blocks of 4 x 4 particles, one spacing apart, closing at 10 m/s."""
    size = [4 * DX] * dim
    bodies = [{"name": name, "material": "m", "velocity": [v] + [0.0] * (dim - 1),
               "geometry": {"origin": [x0] + [0.0] * (dim - 1), "size": size,
                            "spacing": DX}}
              for name, x0, v in (("left", 0.0, 5.0), ("right", 4 * DX, -5.0))]
    case = validate_case({
        "name": "blocks", "dimension": dim,
        "materials": {"m": {"model": "elastic", "density": RHO, "youngs_modulus": E,
                            "shear_modulus": MU}},
        "bodies": bodies, "kernel": {"h_over_dx": 1.3},
        "contact": {"traction": traction},
        "viscosity": {"alpha1": 0.0, "alpha2": 0.0},
        "time": {"end": 1e-6}, "output": {"figures": False}})
    return Simulation(case)


def stressed(sim: Simulation) -> None:
    """Give every particle a compressed density and a deviatoric stress of its own."""
    s = sim.state
    rng = np.random.default_rng(1)
    s.density[:] = RHO * (1.0 + rng.uniform(0.001, 0.003, s.n))
    S = rng.uniform(-2e8, 2e8, (s.n, 3, 3))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    S -= np.trace(S, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    s.deviatoric_stress[:] = S
    s.velocity += rng.uniform(-1.0, 1.0, s.velocity.shape)


def test_normal_stress_contact_is_the_pair_formula_in_1d():
    """In 1D the normal stress along the line of centres is sigma_xx = -P + S_xx: the push of
    the right body on the left body's last particle is -m_j (sn_i + sn_j) dW/dx with
    sn = -sigma_xx / rho^2, and with the pressure traction the same with sn = P / rho^2."""
    got = {}
    for traction in ("pressure", "normal_stress"):
        sim = two_blocks(traction, dim=1)
        s = sim.state
        s.velocity[:] = 0.0
        s.density[:] = RHO * 1.002
        s.deviatoric_stress[:, 0, 0] = np.where(s.body == 0, -3e8, -1e8)
        s.deviatoric_stress[:, 1, 1] = s.deviatoric_stress[:, 2, 2] = \
            -0.5 * s.deviatoric_stress[:, 0, 0]
        sim.solver.rates(s)
        P = sim.solver.pressure(s)
        i = int(np.argmax(np.where(s.body == 0, s.position[:, 0], -np.inf)))  # left's last
        total = 0.0
        for j in np.nonzero(s.body == 1)[0]:
            r = s.position[i, 0] - s.position[j, 0]
            h = s.smoothing_length[i]
            gradw = cubic_spline_dwdr(abs(r), h, 1) * math.copysign(1.0, r)
            sn = [(P[k] - (s.deviatoric_stress[k, 0, 0] if traction == "normal_stress"
                           else 0.0)) / s.density[k] ** 2 for k in (i, j)]
            total += -s.mass[j] * max(sum(sn), 0.0) * gradw
        got[traction] = (sim.solver.buffers.contact_force[i, 0] / s.mass[i], total)
    for traction, (force, want) in got.items():
        assert force == pytest.approx(want, rel=1e-12), traction
    # the deviatoric part pushes harder here (S_xx < 0: compressive along x)
    assert got["pressure"][0] < 0.0  # pushed back, to -x
    assert abs(got["normal_stress"][0]) > 1.5 * abs(got["pressure"][0])


@pytest.mark.parametrize("dim", [2, 3])
def test_normal_stress_contact_conserves_momentum_and_energy(dim):
    sim = two_blocks("normal_stress", dim)
    stressed(sim)
    s = sim.state
    dv, drho, de, dS, _ = sim.solver.rates(s)
    m = s.mass
    assert np.abs(sim.solver.buffers.contact_force[: s.n]).max() > 0  # the blocks touch
    scale = np.sum(m[:, None] * np.abs(s.velocity * dv[: s.n]))
    assert np.abs(m @ dv[: s.n]).max() < 1e-12 * np.abs(m[:, None] * dv[: s.n]).sum()
    power = np.sum(m[:, None] * s.velocity * dv[: s.n]) + m @ de[: s.n]
    assert abs(power) < 1e-12 * scale


def layer_table() -> np.ndarray:
    table = np.zeros((1, 8))
    table[0, RHO0] = RHO
    table[0, BULK] = E / 3.0
    return table


def layer_push_as_before(n, x, v, m, material, table, points, normals, layer, dv, de,
                         per_radian=False):
    """The layer's push as :func:`layer_push` computed it before its quick test of the
    distance (2026-12-06), in numpy over the particles: the area's power for every
    particle, then each wall's test, wall by wall (the same operations in the same order
    for each particle)."""
    rho0 = table[material[:n], RHO0]
    bulk = table[material[:n], BULK]
    area = m[:n] / (rho0 * np.maximum(x[:n, 0], 1e-300)) if per_radian else m[:n] / rho0
    # (the C library's power, as the compiled code calls it: numpy's own vectorised power
    # may differ in the last place)
    spacing = np.array([a ** (1.0 / x.shape[1]) for a in area.tolist()])
    r0 = layer * spacing
    force = np.zeros(x.shape[1])
    for point, normal in zip(points, normals, strict=True):
        d = ((x[:n] - point) * normal).sum(axis=1)
        vn = (v[:n] * normal).sum(axis=1)
        inside = d < r0
        omega = np.sqrt(bulk / (rho0 * r0 * spacing))
        push = omega * omega * (r0 - d) - 2.0 * LAYER_DAMPING * omega * vn
        pushed = inside & (push > 0.0)
        dv[:n][pushed] += push[pushed, None] * normal
        de[:n][pushed] -= push[pushed] * vn[pushed]
        force += (m[:n, None][pushed] * push[pushed, None] * normal).sum(axis=0)
    return force


@pytest.mark.parametrize(("dim", "per_radian"), [(1, False), (2, False), (3, False),
                                                 (2, True)])
def test_layers_quick_test_keeps_every_push_to_the_bit(dim, per_radian):
    """The quick test of the distance (no power of the area for a particle beyond its layer
    of every wall) takes the same particles as the exact test, those within a unit in the
    last place of ``r0`` on either side included, and their pushes are the same to the bit:
    two walls (one near, one at an angle in 2D and 3D), particles of several masses."""
    rng = np.random.default_rng(7)
    layer = 0.25
    n_side = 40
    table = layer_table()
    x = rng.uniform(1.0, 3.0, (3 * n_side, dim)) * DX  # off the axis: r > 0 in axisymmetry
    m = RHO * DX**dim * rng.uniform(0.5, 2.0, 3 * n_side)
    if per_radian:  # the mass per radian of a ring of radius r
        m *= x[:, 0]
    v = rng.normal(0.0, 1.0, (3 * n_side, dim))
    v[:, -1] = -np.abs(v[:, -1])  # approaching the first wall: the push is not zero
    points = np.zeros((2, dim))
    normals = np.zeros((2, dim))
    normals[0, -1] = 1.0
    points[1, 0] = 10.0 * DX  # far from every particle ...
    normals[1, 0] = -1.0
    if dim > 1:  # ... and at an angle
        normals[1] = -np.ones(dim) / math.sqrt(dim)
    for i in range(3 * n_side):  # distances from the first wall at r0, a ulp inside, outside
        area = m[i] / (RHO * x[i, 0]) if per_radian else m[i] / RHO
        r0 = layer * area ** (1.0 / dim)
        x[i, -1] = (r0, np.nextafter(r0, 0.0), np.nextafter(r0, 1.0))[i % 3]
        if i >= 2 * n_side:  # and some well inside or behind it
            x[i, -1] = r0 * rng.uniform(-0.5, 0.9)
    n = x.shape[0]
    dv, de = np.zeros((n, dim)), np.zeros(n)
    dv_want, de_want = np.zeros((n, dim)), np.zeros(n)
    material = np.zeros(n, np.int32)
    total = layer_push(n, x, v, m, material, table, points, normals, layer, dv, de,
                       per_radian)
    want = layer_push_as_before(n, x, v, m, material, table, points, normals, layer,
                                dv_want, de_want, per_radian)
    pushed = de_want != 0.0
    assert 0 < pushed.sum() < n  # the ulp inside is pushed, r0 and the ulp outside are not
    assert not pushed[:2 * n_side:3].any() and pushed[1:2 * n_side:3].all()
    assert np.array_equal(dv, dv_want) and np.array_equal(de, de_want)
    np.testing.assert_allclose(total, want, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_layer_pushes_a_particle_inside_it_and_books_the_work(dim):
    n = np.zeros(dim)
    n[-1] = 1.0
    points, normals = np.zeros((1, dim)), n[None, :].copy()
    m = RHO * DX**dim
    layer = 0.25
    r0 = layer * DX
    d = np.array([0.1 * DX, 0.3 * DX, 0.1 * DX, 0.1 * DX])  # inside, outside, inside, inside
    vn = np.array([-2.0, -2.0, 0.0, 1e6])  # approaching, -, at rest, leaving fast
    x = np.zeros((4, dim))
    x[:, -1] = d
    v = np.zeros((4, dim))
    v[:, -1] = vn
    if dim > 1:
        v[:, 0] = 3.0  # sliding along the wall: no force from it (frictionless)
    dv, de = np.zeros((4, dim)), np.zeros(4)
    total = layer_push(4, x, v, np.full(4, m), np.zeros(4, np.int32), layer_table(), points,
                       normals, layer, dv, de)
    omega = math.sqrt((E / 3.0) / (RHO * r0 * DX))
    want = omega**2 * (r0 - d) - 2.0 * LAYER_DAMPING * omega * vn
    want[1] = want[3] = 0.0  # outside the layer; pulled back would be a pull: none
    assert dv[:, -1] == pytest.approx(want, rel=1e-12)
    if dim > 1:
        assert np.all(dv[:, :-1] == 0.0)
    assert de == pytest.approx(-want * vn, rel=1e-12, abs=0.0)  # v . a from the energy
    assert total[-1] == pytest.approx(m * want.sum(), rel=1e-12)
    # the spring is as stiff as the material: a pressure of K delta / r0 over dx^(dim-1)
    assert m * omega**2 * r0 == pytest.approx((E / 3.0) * DX ** (dim - 1), rel=1e-12)
