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
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike

#: wall kinds (``Walls.kinds``); module-level ints, so compile-time constants in the kernels
FREE_SLIP, NO_SLIP = 1, 2
#: the kind of each ``slip`` name of a case's wall
SLIP_KINDS = {"free": FREE_SLIP, "no": NO_SLIP}


@dataclass
class Walls:
    """The rigid walls of a case, in array form."""

    points: np.ndarray  #: (n_walls, dim)
    normals: np.ndarray  #: (n_walls, dim), unit
    kinds: np.ndarray  #: (n_walls,) FREE_SLIP or NO_SLIP

    @classmethod
    def from_planes(cls, points: ArrayLike, normals: ArrayLike, slips: Sequence[str],
                    dim: int) -> Walls:
        """Walls through ``points`` with ``normals`` (into the material, any length: they
        are normalised) and slip names of :data:`SLIP_KINDS` (``"free"``, ``"no"``), one
        of each per wall; no wall at all is allowed."""
        normals = np.array(normals, dtype=np.float64).reshape(-1, dim)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        return cls(np.array(points, dtype=np.float64).reshape(-1, dim), normals,
                   np.array([SLIP_KINDS[s] for s in slips], dtype=np.int8))

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

    def first_behind(self, x: np.ndarray) -> int:
        """The first particle behind a wall (``d < 0``), or -1."""
        return int(_first_behind(x, self.points, self.normals))

    def select(self, x: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Sources and walls of the ghosts: particles with ``0 <= d < reach``."""
        d = self.distances(x)
        src, wall = np.nonzero((d >= 0.0) & (d < reach))
        return src.astype(np.int64), wall.astype(np.int64)


def walls_of(specs: Iterable[Any], dim: int) -> Walls:
    """The walls described by objects with ``point``, ``normal`` and ``slip`` attributes, such
    as a case's ``boundaries``."""
    specs = list(specs)
    return Walls.from_planes([w.point for w in specs], [w.normal for w in specs],
                             [w.slip for w in specs], dim)


@nb.njit(cache=True)
def _enforce(x, v, m, points, normals, impulse):
    """:meth:`Walls.enforce` for each wall in turn; adds the impulse, returns the count."""
    dim = x.shape[1]
    moved = 0
    for w in range(points.shape[0]):
        for i in range(x.shape[0]):
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
def _first_behind(x, points, normals):
    for i in range(x.shape[0]):
        for w in range(points.shape[0]):
            d = 0.0
            for a in range(x.shape[1]):
                d += (x[i, a] - points[w, a]) * normals[w, a]
            if d < 0.0:
                return i
    return -1


@nb.njit(parallel=True, cache=True)
def fill_ghosts(src, wall, points, normals, kinds, n_real, x, v, rho, e, S, m, h, material,
                body, ghost_body0):
    """Write the ghosts' states into rows ``n_real + k`` of the extended arrays."""
    dim = x.shape[1]
    for k in nb.prange(src.shape[0]):
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
        m[g] = m[i]
        h[g] = h[i]
        material[g] = material[i]
        body[g] = ghost_body0 + w
