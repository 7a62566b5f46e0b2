"""Penalty contact between bodies whose particles do not meet through the kernel: the bodies
of the total-Lagrangian formulation, whose kernel and neighbours are those of t = 0 and of
their own body (docs/stabilisation.md, "Contact between total-Lagrangian bodies").

Each particle has a contact diameter ``d_i = scale dx_i``, ``dx_i = (m_i / rho0_i)^(1/dim)``
its spacing (its share of the body's volume), so that two bodies' particles touch when the
bodies' surfaces, half a spacing beyond their outermost particles, do.  A pair of particles of
different bodies closer than ``d_ij = (d_i + d_j) / 2`` overlaps by ``delta = d_ij - r_ij``
and is pushed apart along ``e_ij = (x_i - x_j) / r_ij`` by Hertz's force between two elastic
spheres of diameter ``d_ij`` (effective radius ``d_ij / 4``; Johnson, *Contact Mechanics*
(1985), eq 4.23), taken as the law in every dimension with ``d_ij^(dim-1)`` the pair's
cross-section (a force per metre of depth in 2D), as LAMMPS SMD's ``smd/hertz`` pushes its
total-Lagrangian bodies apart::

    (PC-1) F_ij = 2/3 k K*_ij d_ij^(dim-1) (delta / d_ij)^(3/2),   1/K*_ij = 1/K_i + 1/K_j
    (PC-2) dv_i/dt += F_ij e_ij / m_i
    (PC-3) de_i/dt -= F_ij (e_ij . v_ij) / (2 m_i),                 v_ij = v_i - v_j

with ``K`` the materials' bulk moduli in series (the wall layer's stiffness,
:func:`impactsph.boundaries.layer_push`, is the bulk modulus too) and ``k`` the case's
``contact.penalty_stiffness``.  (PC-1) is minus the derivative of the potential ``U_ij = 4/15
k K* d_ij^dim (delta / d_ij)^(5/2)``, and (PC-3) books its change in the two particles'
internal energies, half each: the total (kinetic plus internal) energy is kept exactly by
the semi-discrete equations, the contact's elastic energy held as heat while the pair is
pressed together and given back as it separates.  The force is antisymmetric, so momentum is
kept to round-off.  There is no dashpot and no friction.

The candidates are the pairs of different bodies closer than the largest ``d_ij`` plus a
skin, found by the cell list of :class:`impactsph.neighbours.NeighbourList` and held in a
list of particle numbers in increasing order (:func:`contact_pairs`), so that the sums do
not depend on when the list was built (a run continued from a checkpoint rebuilds it).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..boundaries import plane_distance
from ..materials import BULK, RHO0
from ..neighbours import NeighbourList, particle_order_list


def contact_diameters(m: np.ndarray, material: np.ndarray, table: np.ndarray, dim: int,
                      scale: float = 1.0) -> np.ndarray:
    """Each particle's contact diameter ``scale (m_i / rho0_i)^(1/dim)`` (m)."""
    return scale * (m / table[material, RHO0]) ** (1.0 / dim)


def contact_pairs(nl: NeighbourList, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of different bodies of a neighbour list, as a list in particle order (CSR:
    the candidates of ``i`` are ``partners[offsets[i]:offsets[i + 1]]``, increasing)."""
    rows, cols = nl.particle_pairs()
    keep = body[rows] != body[cols]
    return particle_order_list(rows[keep], cols[keep], nl.offsets.shape[0] - 1)


@nb.njit(inline="always", cache=True)
def hertz_pair(i, j, x, v, m, material, table, diameter, stiffness, dv, de,
               contact_force) -> None:
    """(PC-1) to (PC-3) for particle ``i`` of the pair ``(i, j)``, added to ``dv[i]`` and
    ``de[i]``, and its force (N) to ``contact_force[i]``."""
    dim = x.shape[1]
    d_ij = 0.5 * (diameter[i] + diameter[j])
    r2 = 0.0
    for a in range(dim):
        dx = x[i, a] - x[j, a]
        r2 += dx * dx
    if r2 >= d_ij * d_ij or r2 == 0.0:
        return
    r = math.sqrt(r2)
    overlap = (d_ij - r) / d_ij
    k_i = table[material[i], BULK]
    k_j = table[material[j], BULK]
    k_star = k_i * k_j / (k_i + k_j)
    force = (2.0 / 3.0) * stiffness * k_star * d_ij ** (dim - 1) * overlap * math.sqrt(overlap)
    per_length = force / r
    per_mass = per_length / m[i]
    closing = 0.0
    for a in range(dim):
        e_a = x[i, a] - x[j, a]
        dv[i, a] += per_mass * e_a
        contact_force[i, a] += per_length * e_a
        closing += e_a * (v[i, a] - v[j, a])
    de[i] -= 0.5 * per_mass * closing


@nb.njit(parallel=True, cache=True)
def hertz_contact(n, x, v, m, material, table, diameter, offsets, partners, stiffness, dv, de,
                  contact_force):
    """(PC-1) to (PC-3) for the first ``n`` particles over their candidates ``partners``
    (:func:`contact_pairs`), added to ``dv`` and ``de``; ``contact_force[i]`` is set to the
    force (N; N/m in 2D) that the other bodies exert on particle ``i``."""
    dim = x.shape[1]
    for i in nb.prange(n):
        for a in range(dim):
            contact_force[i, a] = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            hertz_pair(i, partners[k], x, v, m, material, table, diameter, stiffness, dv, de,
                       contact_force)


@nb.njit(inline="always", cache=True)
def wall_law(bulk, diameter, z, stiffness, dim):
    """(PC-4) for a particle of bulk modulus ``bulk`` and contact diameter ``diameter`` at
    the distance ``z`` from a wall: ``(F, dF/dz)``, the push (N; N/m in 2D) and its
    stiffness, both 0 off the wall."""
    overlap = (diameter - 2.0 * z) / diameter
    if overlap <= 0.0:
        return 0.0, 0.0
    root = math.sqrt(overlap)
    force = (2.0 / 3.0) * stiffness * 0.5 * bulk * diameter ** (dim - 1) * overlap * root
    return force, 2.0 * stiffness * 0.5 * bulk * diameter ** (dim - 2) * root


@nb.njit(parallel=True, cache=True)
def hertz_wall(n, x, v, m, material, table, diameter, points, normals, stiffness, dv, de,
               wall_force):
    """The rigid walls' push on the first ``n`` particles of a total-Lagrangian run, added to
    ``dv`` and ``de``; ``wall_force[i]`` is set to the force (N; N/m in 2D) that the walls
    exert on particle ``i``.

    A frictionless rigid wall is the mirror plane of two identical bodies pressed together,
    so a particle at the distance ``z_i = (x_i - p) . n`` from a wall through ``p`` with unit
    normal ``n`` (into the material) is pushed as by (PC-1) from its mirror image, ``2 z_i``
    away, of its own material (``K* = K_i / 2``)::

        (PC-4) delta = d_i - 2 z_i,   F_i = 2/3 k (K_i / 2) d_i^(dim-1) (delta / d_i)^(3/2)
        (PC-5) dv_i/dt += F_i n / m_i,   de_i/dt -= F_i (n . v_i) / m_i

    while ``delta > 0``: the push starts as the particle's surface, half its contact diameter
    ahead of it, meets the wall.  (PC-4) is minus the derivative in ``z_i`` of half the mirror
    pair's potential; (PC-5) books its change in the particle's internal energy, so the
    semi-discrete equations keep the total energy, and a body on a wall moves as one of two
    identical bodies meeting head-on."""
    dim = x.shape[1]
    for i in nb.prange(n):
        k_i = table[material[i], BULK]
        for a in range(dim):
            wall_force[i, a] = 0.0
        for w in range(points.shape[0]):
            z = plane_distance(x, i, points, normals, w)
            force, _ = wall_law(k_i, diameter[i], z, stiffness, dim)
            if force == 0.0:
                continue
            vn = 0.0
            for a in range(dim):
                vn += v[i, a] * normals[w, a]
            per_mass = force / m[i]
            for a in range(dim):
                dv[i, a] += per_mass * normals[w, a]
                wall_force[i, a] += force * normals[w, a]
            de[i] -= per_mass * vn


@nb.njit(cache=True)
def wall_frequency(n, x, m, material, table, diameter, points, normals, stiffness):
    """The largest ``omega = sqrt((dF/dz) / m)`` (1/s) of the first ``n`` particles on the
    walls' push (PC-4) at ``x``, 0 with none on a wall (the time step's limit,
    :meth:`impactsph.tl_solver.TotalLagrangianSolver.step_limit`)."""
    dim = x.shape[1]
    largest = 0.0
    for i in range(n):
        spring = 0.0
        for w in range(points.shape[0]):
            z = plane_distance(x, i, points, normals, w)
            spring += wall_law(table[material[i], BULK], diameter[i], z, stiffness, dim)[1]
        largest = max(largest, spring / m[i])
    return math.sqrt(largest)


class PenaltyContact:
    """The contact between the bodies of a total-Lagrangian run: its candidate list (rebuilt
    when a particle has moved half its skin) and :func:`hertz_contact`.

    ``scale``: the contact diameter in spacings (``contact.penalty_distance``); ``stiffness``:
    ``k`` of (PC-1) (``contact.penalty_stiffness``)."""

    #: the candidate list's skin, in largest contact diameters
    SKIN = 0.5

    def __init__(self, m: np.ndarray, material: np.ndarray, body: np.ndarray,
                 table: np.ndarray, dim: int, scale: float = 1.0, stiffness: float = 1.0):
        self.table = table
        self.body = np.ascontiguousarray(body)
        self.stiffness = float(stiffness)
        self.diameter = contact_diameters(m, material, table, dim, scale)
        self.reach = float(self.diameter.max()) if self.diameter.size else 0.0
        self.list: NeighbourList | None = None
        self.offsets = np.zeros(m.shape[0] + 1, dtype=np.int64)
        self.partners = np.zeros(0, dtype=np.int32)
        self.builds = 0

    def _refresh(self, x: np.ndarray) -> None:
        if self.list is None or self.list.stale(x, self.reach):
            self.list = NeighbourList.build(x, self.reach, self.SKIN * self.reach)
            self.offsets, self.partners = contact_pairs(self.list, self.body)
            self.builds += 1

    def add(self, n: int, x: np.ndarray, v: np.ndarray, m: np.ndarray, material: np.ndarray,
            dv: np.ndarray, de: np.ndarray, contact_force: np.ndarray) -> None:
        """Add the contact's (PC-2) and (PC-3) of particles at ``x`` moving at ``v`` to
        ``dv`` and ``de``, and set each particle's contact force (N) in ``contact_force``."""
        self._refresh(x[:n])
        hertz_contact(n, x, v, m, material, self.table, self.diameter, self.offsets,
                      self.partners, self.stiffness, dv, de, contact_force)
