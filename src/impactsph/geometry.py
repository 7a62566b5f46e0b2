"""Particle geometry: lattices of particles filling simple shapes."""

from __future__ import annotations

import numpy as np


def block_lattice(origin: list[float], size: list[float], spacing: float) -> np.ndarray:
    """Particles at the cell centres of a regular lattice filling the box
    ``[origin, origin + size]``: ``round(size / spacing)`` particles per axis.
    Returns positions of shape ``(n, dim)``, x fastest."""
    origin = np.asarray(origin, dtype=np.float64)
    counts = np.maximum(1, np.rint(np.asarray(size) / spacing).astype(int))
    axes = [origin[a] + (np.arange(counts[a]) + 0.5) * spacing for a in range(origin.size)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel(order="F") for g in grid], axis=1)
