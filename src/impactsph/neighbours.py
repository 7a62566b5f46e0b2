"""Neighbour search by a cell-linked list, cost linear in the number of particles.

Particles are binned into cubic cells whose edge is at least the search radius, so every
neighbour of a particle lies in its own cell or one of the ``3**dim - 1`` cells around it.
The result is a compressed (CSR) list: the neighbours of particle ``i`` are
``indices[offsets[i]:offsets[i + 1]]`` (``i`` itself excluded), every ``j`` with
``|x_i - x_j| < radius``.

The list is built with a *skin*: the search radius is ``2 h_max + skin``, and the list stays
valid until some particle has moved more than ``skin / 2`` from where it was when the list
was built (:class:`NeighbourList.needs_rebuild`).  Pairs beyond the kernel's support are then
skipped by the pair loops, whose kernel value is zero there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numba as nb
import numpy as np


@cache
def _build_functions(dim: int):
    """Compile the cell-list builder for one dimension (``dim`` is a compile-time constant)."""
    n_stencil = 3**dim

    @nb.njit(cache=True)
    def cell_coordinates(x, lo, cell, ncell):
        n = x.shape[0]
        key = np.empty(n, dtype=np.int64)
        for i in range(n):
            k = 0
            for a in range(dim):
                c = int((x[i, a] - lo[a]) / cell)
                if c < 0:
                    c = 0
                if c >= ncell[a]:
                    c = ncell[a] - 1
                k = k * ncell[a] + c
            key[i] = k
        return key

    @nb.njit(inline="always", cache=True)
    def visit(i, x, lo, radius, ncell, cell_start, order, r2max, indices, pos, write):
        """Count (and if ``write``, store from ``pos``) the neighbours of particle ``i``."""
        found = 0
        for s in range(n_stencil):
            t = s
            kc = 0
            inside = True
            for a in range(dim):
                c = int((x[i, a] - lo[a]) / radius)
                c = min(max(c, 0), ncell[a] - 1) + t % 3 - 1
                t //= 3
                if c < 0 or c >= ncell[a]:
                    inside = False
                kc = kc * ncell[a] + c
            if not inside:
                continue
            for p in range(cell_start[kc], cell_start[kc + 1]):
                j = order[p]
                if j == i:
                    continue
                r2 = 0.0
                for a in range(dim):
                    d = x[i, a] - x[j, a]
                    r2 += d * d
                if r2 < r2max:
                    if write:
                        indices[pos + found] = j
                    found += 1
        return found

    @nb.njit(parallel=True, cache=True)
    def build(x, radius):
        n = x.shape[0]
        lo = np.empty(dim)
        ncell = np.ones(dim, dtype=np.int64)
        if n > 0:
            for a in range(dim):
                lo[a] = x[:, a].min()
                ncell[a] = max(1, int((x[:, a].max() - lo[a]) / radius) + 1)
        total_cells = 1
        for a in range(dim):
            total_cells *= ncell[a]
        key = cell_coordinates(x, lo, radius, ncell)
        order = np.argsort(key, kind="mergesort")
        cell_start = np.zeros(total_cells + 1, dtype=np.int64)
        for i in range(n):
            cell_start[key[i] + 1] += 1
        for c in range(total_cells):
            cell_start[c + 1] += cell_start[c]
        r2max = radius * radius
        offsets = np.zeros(n + 1, dtype=np.int64)
        empty = np.empty(0, dtype=np.int64)
        for i in nb.prange(n):
            offsets[i + 1] = visit(
                i, x, lo, radius, ncell, cell_start, order, r2max, empty, 0, False
            )
        for i in range(n):
            offsets[i + 1] += offsets[i]
        indices = np.empty(offsets[n], dtype=np.int64)
        for i in nb.prange(n):
            visit(i, x, lo, radius, ncell, cell_start, order, r2max, indices, offsets[i], True)
        return offsets, indices

    @nb.njit(cache=True)
    def max_displacement(x, x_ref):
        largest = 0.0
        for i in range(x.shape[0]):
            s = 0.0
            for a in range(dim):
                d = x[i, a] - x_ref[i, a]
                s += d * d
            largest = max(largest, s)
        return math.sqrt(largest)

    return build, max_displacement


@dataclass
class NeighbourList:
    """CSR neighbour list with a Verlet skin.

    ``offsets`` has ``n + 1`` entries; ``indices[offsets[i]:offsets[i+1]]`` are the neighbours
    of ``i`` within ``radius`` at the time of the build; ``reference_positions`` are the
    positions then.
    """

    offsets: np.ndarray
    indices: np.ndarray
    radius: float
    skin: float
    reference_positions: np.ndarray
    builds: int = 1

    @classmethod
    def build(cls, x: np.ndarray, support: float, skin: float = 0.0) -> NeighbourList:
        """All pairs closer than ``support + skin`` (``support`` = 2 h_max for eq 20)."""
        dim = x.shape[1]
        build, _ = _build_functions(dim)
        radius = float(support + skin)
        offsets, indices = build(np.ascontiguousarray(x), radius)
        return cls(offsets, indices, radius, float(skin), x.copy())

    def needs_rebuild(self, x: np.ndarray) -> bool:
        """True once any particle has moved more than half the skin since the build."""
        if self.skin <= 0.0:
            return True
        _, max_disp = _build_functions(x.shape[1])
        reference = self.reference_positions[: x.shape[0]]  # ghosts follow their sources
        return bool(max_disp(x, reference) > 0.5 * self.skin)

    def update(self, x: np.ndarray, support: float) -> None:
        """Rebuild in place if the skin no longer covers the motion since the last build."""
        if self.needs_rebuild(x) or support + self.skin > self.radius + 1e-15 * self.radius:
            new = NeighbourList.build(x, support, self.skin)
            self.offsets, self.indices = new.offsets, new.indices
            self.radius, self.reference_positions = new.radius, new.reference_positions
            self.builds += 1

    @property
    def n_pairs(self) -> int:
        """Number of ordered pairs (i, j) stored."""
        return int(self.indices.shape[0])


def brute_force_pairs(x: np.ndarray, radius: float) -> set[tuple[int, int]]:
    """Reference O(N^2) search, for tests: ordered pairs with ``|x_i - x_j| < radius``."""
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    i, j = np.nonzero(d < radius)
    return {(int(a), int(b)) for a, b in zip(i, j, strict=True) if a != b}
