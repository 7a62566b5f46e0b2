"""Rigid walls modelled by ghost particles.

A wall is a plane through ``point`` with unit normal ``n`` pointing into the material.  Every
particle within the kernel's reach of a wall (``0 <= d < reach``, ``d = (x - point) . n``)
gets a ghost, its mirror image::

    x_g = x - 2 d n,      S_g = R S R   (R = I - 2 n n, the reflection)
    v_g = v - 2 (v . n) n     free slip: the normal velocity reflected
    v_g = -v                  no slip: the wall at rest in between

with the density, internal energy, mass and material of its source.  Ghosts take part in the
sums of the real particles but are not integrated.  A ghost interacts with real particles as a
body of its own, through the contact law of :mod:`.physics.contact`: it pushes, never pulls,
and transmits no shear stress; with no slip its mirrored velocity makes the artificial
viscosity resist sliding along the wall as well as approach.
The set of ghosts is chosen when the neighbour list is built (``reach`` includes the
list's skin) and their states follow their sources at every rate evaluation.

The ghosts' push on a particle vanishes as it nears the wall (the kernel gradient is zero at
zero distance), and a layer of particles that thins as it spreads along the wall (as at the
impact face of a 3D Taylor cylinder, where it thins as 1/lambda^2) drifts onto the plane.  The
optional *wall layer* (:func:`layer_push`, ``[contact] wall_layer``) holds it off: a spring
and dashpot on the particles within ``layer`` spacings of the plane, whose work is booked in
their internal energy, so the total energy is kept (docs/stabilisation.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike

from .materials import BULK, RHO0, SHEAR
from .physics.contact import FRICTION_REGULARISATION

#: wall kinds (``Walls.kinds``); module-level ints, so compile-time constants in the kernels
FREE_SLIP, NO_SLIP, SYMMETRY = 1, 2, 3
#: the kind of each ``slip`` name of a case's wall (``"symmetry"``: a symmetry plane)
SLIP_KINDS = {"free": FREE_SLIP, "no": NO_SLIP, "symmetry": SYMMETRY}


@dataclass
class Walls:
    """The rigid walls of a case, in array form."""

    points: np.ndarray  #: (n_walls, dim)
    normals: np.ndarray  #: (n_walls, dim), unit
    kinds: np.ndarray  #: (n_walls,) FREE_SLIP, NO_SLIP or SYMMETRY
    #: (n_walls,) Coulomb friction coefficients (0: frictionless; a symmetry plane's is 0)
    friction: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.friction is None:
            self.friction = np.zeros(self.points.shape[0])

    @classmethod
    def from_planes(cls, points: ArrayLike, normals: ArrayLike, slips: Sequence[str],
                    dim: int, friction: Sequence[float] | None = None) -> Walls:
        """Walls through ``points`` with ``normals`` (into the material, any length: they
        are normalised) and slip names of :data:`SLIP_KINDS` (``"free"``, ``"no"``), one
        of each per wall, and their Coulomb ``friction`` coefficients (default 0); no wall at
        all is allowed."""
        normals = np.array(normals, dtype=np.float64).reshape(-1, dim)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        mu = np.zeros(normals.shape[0]) if friction is None else np.array(friction, dtype=float)
        return cls(np.array(points, dtype=np.float64).reshape(-1, dim), normals,
                   np.array([SLIP_KINDS[s] for s in slips], dtype=np.int8), mu)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def distances(self, x: np.ndarray) -> np.ndarray:
        """Signed distances (n, n_walls) of points to the walls, positive in the material."""
        return np.einsum("iwa,wa->iw", x[:, None, :] - self.points[None], self.normals)

    def enforce(self, x: np.ndarray, v: np.ndarray, m: np.ndarray) -> tuple[int, np.ndarray]:
        """The wall as a constraint, after each integrator stage: a particle found behind a
        wall is put back onto it and loses its velocity into the wall.  The ghosts' pressure
        normally keeps particles off the wall; a particle in tension (which the compression-only
        ghosts do not push) can still reach it, and this guarantees that none crosses.
        Returns the number of particles moved and the impulse given to them (N s)."""
        impulse = np.zeros(x.shape[1])
        moved = _enforce(x, v, m, self.points, self.normals, impulse)
        return moved, impulse

    @property
    def walls_only(self) -> np.ndarray:
        """Indices of the rigid walls (not the symmetry planes)."""
        return np.flatnonzero(self.kinds != SYMMETRY)

    def select(self, x: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Sources and walls (or planes) of the ghosts, in the order they are filled: first
        the rigid walls' ghosts of the particles with ``0 <= d < reach``, then for each
        symmetry plane in turn the mirrors of every row so far (particles and the ghosts
        before it) within ``reach`` of it, so that a particle near a wall and a symmetry
        plane, or near two planes, finds the corner images the whole model would give it.
        A ghost's source is a row before it (:func:`fill_ghosts` fills them in order)."""
        n = x.shape[0]
        rigid = self.walls_only
        d = self.distances(x)[:, rigid] if rigid.size else np.zeros((n, 0))
        src, k = np.nonzero((d >= 0.0) & (d < reach))
        sources, walls = [src.astype(np.int64)], [rigid[k].astype(np.int64)]
        planes = np.flatnonzero(self.kinds == SYMMETRY)
        if planes.size == 0:  # (the ghosts' positions are for the planes' search alone)
            return sources[0], walls[0]
        positions = [x, _mirrored(x[src], self.points[rigid[k]], self.normals[rigid[k]])]
        for w in planes:
            rows = np.concatenate(positions)
            dist = (rows - self.points[w]) @ self.normals[w]
            near = np.flatnonzero((dist >= 0.0) & (dist < reach))
            sources.append(near.astype(np.int64))
            walls.append(np.full(near.size, w, dtype=np.int64))
            positions.append(_mirrored(rows[near], self.points[w][None], self.normals[w][None]))
        return np.concatenate(sources), np.concatenate(walls)


def _mirrored(x: np.ndarray, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Mirror images of points ``x`` across the planes (one per point, or one for all)."""
    d = np.einsum("ia,ia->i", x - points, np.broadcast_to(normals, x.shape))
    return x - 2.0 * d[:, None] * normals


def walls_of(specs: Iterable[Any], dim: int) -> Walls:
    """The walls described by objects with ``point``, ``normal`` and ``slip`` attributes (a
    case's ``boundaries``: a symmetry plane has ``type = "symmetry"``)."""
    specs = list(specs)
    return Walls.from_planes([w.point for w in specs], [w.normal for w in specs],
                             ["symmetry" if getattr(w, "type", "wall") == "symmetry" else w.slip
                              for w in specs], dim,
                             [float(getattr(w, "friction", 0.0)) for w in specs])


@nb.njit(inline="always", cache=True)
def enforce_particle(i, x, v, m, points, normals, impulse):
    """:meth:`Walls.enforce` for particle ``i``, wall by wall: adds its impulse to
    ``impulse`` and returns how many times it was moved (the CPU loop and the kernel of
    :mod:`impactsph.gpu_step` call this)."""
    dim = x.shape[1]
    moved = 0
    for w in range(points.shape[0]):
        d = 0.0
        for a in range(dim):
            d += (x[i, a] - points[w, a]) * normals[w, a]
        if d < 0.0:
            vn = 0.0
            for a in range(dim):
                x[i, a] -= d * normals[w, a]
                vn += v[i, a] * normals[w, a]
            dvn = -min(vn, 0.0)
            for a in range(dim):
                v[i, a] += dvn * normals[w, a]
                impulse[a] += m[i] * dvn * normals[w, a]
            moved += 1
    return moved


@nb.njit(cache=True)
def _enforce(x, v, m, points, normals, impulse):
    """:meth:`Walls.enforce` for each particle in turn; adds the impulse, returns the count."""
    moved = 0
    for i in range(x.shape[0]):
        moved += enforce_particle(i, x, v, m, points, normals, impulse)
    return moved


@nb.njit(inline="always", cache=True)
def plane_distance(x, i, points, normals, w):
    """Signed distance of ``x[i]`` from plane ``w`` (m), positive on the side its normal
    points to (the material's).  For the CPU's loops; the kernels shared with
    :mod:`impactsph.gpu_step` write the sum out, as CUDA compiles them."""
    d = 0.0
    for a in range(x.shape[1]):
        d += (x[i, a] - points[w, a]) * normals[w, a]
    return d


@nb.njit(cache=True)
def fill_ghosts(src, wall, points, normals, kinds, n_real, x, v, rho, e, S, carried, m, h,
                material, body, ghost_body0):
    """Write the ghosts' states into rows ``n_real + k`` of the extended arrays, in order (a
    symmetry plane's ghost may mirror an earlier ghost): :func:`fill_ghost` for each."""
    for k in range(src.shape[0]):
        fill_ghost(k, src, wall, points, normals, kinds, n_real, x, v, rho, e, S, carried, m,
                   h, material, body, ghost_body0)


@nb.njit(inline="always", cache=True)
def fill_ghost(k, src, wall, points, normals, kinds, n_real, x, v, rho, e, S, carried, m, h,
               material, body, ghost_body0):
    """Ghost ``k``'s state in row ``n_real + k``: its source's mirrored across its plane.  A
    rigid wall's ghost is a body of its own (``ghost_body0 + w``: the contact law); a symmetry
    plane's ghost belongs to its source's body, so it interacts as the mirrored half of the
    model would."""
    dim = x.shape[1]
    i = src[k]
    w = wall[k]
    g = n_real + k
    d = 0.0
    vn = 0.0
    for a in range(dim):
        d += (x[i, a] - points[w, a]) * normals[w, a]
        vn += v[i, a] * normals[w, a]
    for a in range(dim):
        x[g, a] = x[i, a] - 2.0 * d * normals[w, a]
        if kinds[w] == NO_SLIP:
            v[g, a] = -v[i, a]
        else:
            v[g, a] = v[i, a] - 2.0 * vn * normals[w, a]
    # S_g = R S R with R = I - 2 n n (in-plane components of n; n_z = 0 in 2D)
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for c in range(3):
                rac = (1.0 if a == c else 0.0) - (
                    2.0 * normals[w, a] * normals[w, c] if a < dim and c < dim else 0.0)
                for d2 in range(3):
                    rdb = (1.0 if d2 == b else 0.0) - (
                        2.0 * normals[w, d2] * normals[w, b] if d2 < dim and b < dim
                        else 0.0)
                    acc += rac * S[i, c, d2] * rdb
            S[g, a, b] = acc
    rho[g] = rho[i]
    e[g] = e[i]
    for c in range(carried.shape[1]):  # the common material state (damage, thickness)
        carried[g, c] = carried[i, c]
    m[g] = m[i]
    h[g] = h[i]
    material[g] = material[i]
    body[g] = body[i] if kinds[w] == SYMMETRY else ghost_body0 + w


@nb.njit(inline="always", cache=True)
def reflect(M, normal, dim, out):
    """``out = R M R`` with ``R = I - 2 n n``, for ``dim x dim`` matrices."""
    for a in range(dim):
        for b in range(dim):
            acc = 0.0
            for c in range(dim):
                rac = (1.0 if a == c else 0.0) - 2.0 * normal[a] * normal[c]
                for d in range(dim):
                    rdb = (1.0 if d == b else 0.0) - 2.0 * normal[d] * normal[b]
                    acc += rac * M[c, d] * rdb
            out[a, b] = acc


@nb.njit(cache=True)
def mirrors_a_symmetric_row(src, wall, kinds, n_real, k):
    """Whether ghost ``k`` is a symmetry plane's image of a real particle or of another
    symmetry image (a corner image near two planes), whose per-particle results it takes
    mirrored; not a rigid wall's ghost, nor an image of one."""
    if kinds[wall[k]] != SYMMETRY:
        return False
    i = src[k]
    while i >= n_real:  # a chain of images ends at a real particle, through symmetry planes
        k = i - n_real
        if kinds[wall[k]] != SYMMETRY:
            return False
        i = src[k]
    return True


@nb.njit(cache=True)
def mirror_ghost_results(src, wall, normals, kinds, n_real, position, P, u_column, dim,
                         gradients):
    """After the pair pass: give each symmetry-plane ghost of a particle the mirror of that
    particle's per-particle results that later passes read, as the mirrored half of the model
    would have them: its viscous acceleration ``u`` in the packed records (the acceleration
    correction reads it; records without those columns have none to mirror) and its velocity
    gradient ``L_g = R L R`` (the hourglass control reads it; ``gradients`` has no rows when
    that is off).  ``position[row]`` is the row's
    place in the packed records.  A corner image (the ghost of a symmetry ghost, near two
    planes) mirrors its source ghost's results, mirrored before it (the ghosts are in order):
    the composition of the two reflections, as the whole model has it."""
    for k in range(src.shape[0]):
        mirror_ghost_result(k, src, wall, normals, kinds, n_real, position, P, u_column, dim,
                            gradients)


@nb.njit(inline="always", cache=True)
def mirror_ghost_result(k, src, wall, normals, kinds, n_real, position, P, u_column, dim,
                        gradients):
    """:func:`mirror_ghost_results` for ghost ``k`` (the CPU loop and the kernel of
    :mod:`impactsph.gpu_step` call this)."""
    if not mirrors_a_symmetric_row(src, wall, kinds, n_real, k):
        return
    w = wall[k]
    pg = position[n_real + k]
    pi = position[src[k]]
    if P.shape[1] > u_column:  # the records carry u (a correction or switch reads it)
        un = 0.0
        for a in range(dim):
            un += P[pi, u_column + a] * normals[w, a]
        for a in range(dim):
            P[pg, u_column + a] = P[pi, u_column + a] - 2.0 * un * normals[w, a]
    if gradients.shape[0] > 0:
        reflect(gradients[pi], normals[w], dim, gradients[pg])


@nb.njit(cache=True)
def mirror_ghost_matrices(src, wall, normals, kinds, n_real, position, P, c0, dim):
    """After the correction matrices (the kernel gradient correction of the forces): give
    each symmetry-plane ghost of a particle the mirror ``R C R`` of that particle's matrix,
    which its own neighbourhood (cut at the ghosts' reach) would get wrong.  ``C`` is stored
    row by row from record column ``c0``; the same for any matrix stored so (the velocity
    gradients of a reconstructing viscosity).  A corner image gets the mirror of its source
    ghost's, as in :func:`mirror_ghost_results`."""
    source = np.empty((dim, dim))
    mirrored = np.empty((dim, dim))
    for k in range(src.shape[0]):
        mirror_ghost_matrix(k, src, wall, normals, kinds, n_real, position, P, c0, dim,
                            source, mirrored)


@nb.njit(inline="always", cache=True)
def mirror_ghost_matrix(k, src, wall, normals, kinds, n_real, position, P, c0, dim, source,
                        mirrored):
    """:func:`mirror_ghost_matrices` for ghost ``k``, ``source`` and ``mirrored`` its
    ``dim x dim`` scratch (the CPU loop and the kernel of :mod:`impactsph.gpu_step` call
    this)."""
    if not mirrors_a_symmetric_row(src, wall, kinds, n_real, k):
        return
    pg = position[n_real + k]
    pi = position[src[k]]
    for a in range(dim):
        for b in range(dim):
            source[a, b] = P[pi, c0 + a * dim + b]
    reflect(source, normals[wall[k]], dim, mirrored)
    for a in range(dim):
        for b in range(dim):
            P[pg, c0 + a * dim + b] = mirrored[a, b]




@nb.njit(cache=True)
def friction_push(n, x, v, m, material, table, contact_force, points, normals, mu, reach,
                  dv, de):
    """Coulomb friction of the rigid walls on the first ``n`` particles, added to ``dv`` and
    ``de``; returns the total force on them (N, or N/m in 2D).

    A particle within ``reach`` of wall ``w`` (``0 <= d < reach``) that the wall pushes with
    the normal force ``f_n = max(0, f_c . n_w)`` (``f_c`` its contact force: the ghosts'
    push) is slowed along the wall by::

        dv_i/dt += -mu_w f_n / m_i  v_t / sqrt(|v_t|^2 + v_r^2)
        de_i/dt -= v_i . (that acceleration)             (the friction's work, as heat)

    with ``v_t`` its velocity along the wall and ``v_r = FRICTION_REGULARISATION c_l`` the
    regularising speed (``c_l`` the longitudinal wave speed at rho0): Coulomb's law
    ``|f_t| = mu f_n`` while it slides faster than ``v_r``.  The heat keeps the total
    energy."""
    total = np.zeros(x.shape[1])
    for w in range(points.shape[0]):
        if mu[w] <= 0.0:
            continue
        for i in range(n):
            friction_particle(i, w, x, v, m, material, table, contact_force, points, normals,
                              mu, reach, dv, de, total)
    return total


@nb.njit(inline="always", cache=True)
def friction_particle(i, w, x, v, m, material, table, contact_force, points, normals, mu,
                      reach, dv, de, force):
    """Wall ``w``'s Coulomb friction on particle ``i`` (:func:`friction_push`'s law), added
    to ``dv[i]`` and ``de[i]``, its force (N) to ``force`` (the CPU loop and the kernel of
    :mod:`impactsph.gpu_step` call this)."""
    dim = x.shape[1]
    d = 0.0
    fn = 0.0
    vn = 0.0
    for a in range(dim):
        d += (x[i, a] - points[w, a]) * normals[w, a]
        fn += contact_force[i, a] * normals[w, a]
        vn += v[i, a] * normals[w, a]
    if d < 0.0 or d >= reach or fn <= 0.0:
        return
    k = material[i]
    v_reg = FRICTION_REGULARISATION * math.sqrt(
        (table[k, BULK] + 4.0 / 3.0 * table[k, SHEAR]) / table[k, RHO0])
    vt2 = 0.0
    for a in range(dim):
        vt = v[i, a] - vn * normals[w, a]
        vt2 += vt * vt
    scale = mu[w] * fn / (m[i] * math.sqrt(vt2 + v_reg * v_reg))
    power = 0.0
    for a in range(dim):
        acc = -scale * (v[i, a] - vn * normals[w, a])
        dv[i, a] += acc
        force[a] += m[i] * acc
        power += v[i, a] * acc
    de[i] -= power


#: damping ratio of the wall layer's dashpot: the midpoint integrator amplifies an undamped
#: oscillation (by ``1 + (omega dt)^4 / 8`` a step); half-critical damping makes the layer's
#: stiffest mode decay by a factor 0.65 a step at Courant 0.3
LAYER_DAMPING = 0.5

#: :func:`_near_a_wall`'s margin: a particle with ``d^dim`` over this times ``layer^dim``
#: times its area is beyond ``r0 = layer area^(1/dim)`` whatever the round-off of either
#: side (each within a few units of 1e-16 of its exact value)
LAYER_TEST_MARGIN = 1.0 + 1e-9


@nb.njit(inline="always", cache=True)
def _near_a_wall(i, x, points, normals, far):
    """Whether particle ``i`` may be within its layer of a wall: some wall's distance ``d`` is
    not positive or has ``d^dim <= far`` (``far`` a bound a little above ``r0^dim``).  The
    test needs no power of the area, which cost 24 ns a particle of :func:`layer_push`,
    where most particles are far from the walls (the area's power stands apart from the
    wall loop: inside it, LLVM hoists it out of that loop and runs it for every particle);
    the particles it passes are then pushed exactly as before, to the bit."""
    dim = x.shape[1]
    for w in range(points.shape[0]):
        d = 0.0
        for a in range(dim):
            d += (x[i, a] - points[w, a]) * normals[w, a]
        if not (d > 0.0 and d ** dim > far):
            return True
    return False


@nb.njit(inline="always", cache=True)
def layer_push_particle(i, x, v, m, material, table, points, normals, layer, dv, de,
                        per_radian, force):
    """:func:`layer_push` on particle ``i``: its push added to ``dv[i]``, ``de[i]`` and its
    force (N) to ``force`` (the CPU loop and the kernel of :mod:`impactsph.gpu_step` call
    this)."""
    dim = x.shape[1]
    k = material[i]
    rho0 = table[k, RHO0]
    # axisymmetry (per_radian): the mass is per radian, the particle's area m / (rho0 r)
    area = m[i] / (rho0 * max(x[i, 0], 1e-300)) if per_radian else m[i] / rho0
    if not _near_a_wall(i, x, points, normals, LAYER_TEST_MARGIN * layer ** dim * area):
        return
    dx = area ** (1.0 / dim)
    r0 = layer * dx
    for w in range(points.shape[0]):
        d = 0.0
        vn = 0.0
        for a in range(dim):
            d += (x[i, a] - points[w, a]) * normals[w, a]
            vn += v[i, a] * normals[w, a]
        if d >= r0:
            continue
        omega = math.sqrt(table[k, BULK] / (rho0 * r0 * dx))
        push = omega * omega * (r0 - d) - 2.0 * LAYER_DAMPING * omega * vn
        if push <= 0.0:
            continue
        for a in range(dim):
            dv[i, a] += push * normals[w, a]
            force[a] += m[i] * push * normals[w, a]
        de[i] -= push * vn


@nb.njit(parallel=True, cache=True)
def layer_push(n, x, v, m, material, table, points, normals, layer, dv, de,
               per_radian=False):
    """The wall layer's push on the first ``n`` particles, added to ``dv`` and ``de``; returns
    the total force on them (N, or N per metre of depth in 2D).

    A particle of spacing ``dx_i = (m_i / rho0_i)^(1/dim)`` at distance ``d`` from a wall is in
    the layer while ``d < r0 = layer dx_i``.  With the penetration ``delta = r0 - d``, the
    layer is as stiff as the material (bulk modulus ``K``) over the particle's cross-section
    ``dx_i^(dim-1)`` and thickness ``r0``, with a dashpot of damping ratio ``LAYER_DAMPING``
    on its normal velocity ``v_n``, and it only pushes::

        omega^2 = K / (rho0 r0 dx_i)
        dv_i/dt += max(0, omega^2 delta - 2 zeta omega v_n) n
        de_i/dt -= v_i . (that acceleration)

    The second line keeps the total (kinetic plus internal) energy: the spring's energy is
    held in the particle's internal energy while it is compressed and given back as it
    leaves; the dashpot's work stays there as heat.

    ``per_radian``: an axisymmetric run, whose masses are per radian (the spacing is then ``(m_i /
    (rho0_i r_i))^(1/2)``).  (A total-Lagrangian body, which has no wall ghosts, meets a wall
    through :func:`impactsph.physics.penalty_contact.hertz_wall` instead.)"""
    dim = x.shape[1]
    chunk = 1024
    n_chunks = max(1, (n + chunk - 1) // chunk)
    part = np.zeros((n_chunks, 3))
    for c in nb.prange(n_chunks):
        for i in range(c * chunk, min((c + 1) * chunk, n)):
            layer_push_particle(i, x, v, m, material, table, points, normals, layer, dv, de,
                                per_radian, part[c])
    total = np.zeros(dim)
    for c in range(n_chunks):
        for a in range(dim):
            total[a] += part[c, a]
    return total
