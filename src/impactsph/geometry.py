"""Particle geometry: lattices of particles filling simple shapes."""

from __future__ import annotations

import numpy as np


def block_lattice(origin: list[float], size: list[float], spacing: list[float]) -> np.ndarray:
    """Particles at the cell centres of a regular lattice filling the box
    ``[origin, origin + size]``: ``round(size / spacing)`` particles per axis (``spacing``
    per axis).  Returns positions of shape ``(n, dim)``, x fastest."""
    origin = np.asarray(origin, dtype=np.float64)
    spacing = np.broadcast_to(np.asarray(spacing, dtype=np.float64), origin.shape)
    counts = np.maximum(1, np.rint(np.asarray(size) / spacing).astype(int))
    axes = [origin[a] + (np.arange(counts[a]) + 0.5) * spacing[a] for a in range(origin.size)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel(order="F") for g in grid], axis=1)


def inside(x: np.ndarray, origin: list[float], size: list[float]) -> np.ndarray:
    """Mask of the points inside the closed box ``[origin, origin + size]``."""
    lo = np.asarray(origin, dtype=np.float64)
    hi = lo + np.asarray(size, dtype=np.float64)
    return np.all((x >= lo) & (x <= hi), axis=1)
