"""Cubic-spline kernel (eq 20): normalisation, gradient, support."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from impactsph.kernels import kernel, kernel_derivative


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_kernel_integrates_to_one(dim):
    h = 0.37
    r = np.linspace(0, 2 * h, 20001)
    w = kernel(r, h, dim)
    shell = {1: 2.0, 2: 2 * np.pi * r, 3: 4 * np.pi * r**2}[dim]
    assert integrate.simpson(w * shell, x=r) == pytest.approx(1.0, abs=1e-8)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_derivative_matches_finite_differences(dim):
    h = 1.3
    r = np.linspace(0.01, 2.6, 500)
    r = r[np.abs(r / h - 1.0) > 1e-3]  # skip the joint of the two pieces
    step = 1e-6
    fd = (kernel(r + step, h, dim) - kernel(r - step, h, dim)) / (2 * step)
    np.testing.assert_allclose(kernel_derivative(r, h, dim), fd, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_compact_support_and_shape(dim):
    h = 0.5
    r = np.array([2 * h, 2 * h + 1e-9, 3 * h, 10.0])
    assert np.all(kernel(r, h, dim) == 0.0)
    assert np.all(kernel_derivative(r, h, dim) == 0.0)
    inside = np.linspace(0, 2 * h * 0.999, 200)
    w = kernel(inside, h, dim)
    assert np.all(w > 0) and np.all(np.diff(w) < 0)  # monotonically decreasing
    assert np.all(kernel_derivative(inside[1:], h, dim) < 0)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_lattice_sum_is_close_to_one(dim):
    """The discrete sum of W over a lattice with h = 1.2 dx is near one (partition of unity)."""
    dx, h = 1.0, 1.2
    axis = np.arange(-3, 4) * dx
    grid = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    total = np.sum(kernel(np.linalg.norm(grid, axis=1), h, dim)) * dx**dim
    assert total == pytest.approx(1.0, abs=0.03)
