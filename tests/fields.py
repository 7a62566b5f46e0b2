"""Random fields for the tests that perturb a state."""

from __future__ import annotations

import numpy as np


def random_deviator(rng: np.random.Generator, n: int, dim: int, scale: float) -> np.ndarray:
    """``n`` random symmetric traceless 3x3 tensors (normal entries of standard deviation
    ``scale``, Pa), with no shear out of the plane (or line) of a ``dim`` < 3 model."""
    S = rng.normal(0.0, scale, (n, 3, 3))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    S -= np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    if dim < 3:  # plane strain / uniaxial: no shear out of the plane
        S[:, dim:, :dim] = 0.0
        S[:, :dim, dim:] = 0.0
    return S
