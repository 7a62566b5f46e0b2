"""Cubic-spline smoothing kernel (Shaw & Reid 2009, section 2.3, eq 20).

With ``q = r / h`` the kernel is

    W(q, h) = alpha_D * { 1 - 3/2 q^2 + 3/4 q^3      0 <= q <= 1
                        { 1/4 (2 - q)^3              1 <= q <= 2
                        { 0                          q >= 2

with ``alpha_D = 2/(3h)`` in 1D, ``10/(7 pi h^2)`` in 2D (eq 20) and ``1/(pi h^3)`` in 3D
(the same spline's usual 3D constant; the paper has no 3D example), so that the kernel
integrates to one over its support of radius ``2h``.  The gradient with respect to
``x_i`` is ``grad W_ij = dW/dr * r_ij / r``.

The functions are compiled with numba and inlined into the pair loops of
:mod:`impactsph.physics.rates`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

#: Support radius of the kernel in units of the smoothing length.
SUPPORT_RADIUS = 2.0


@nb.njit(inline="always", cache=True)
def normalisation(h: float, dim: int) -> float:
    """The constant ``alpha_D`` of eq 20 for dimension ``dim``."""
    if dim == 1:
        return 2.0 / (3.0 * h)
    if dim == 2:
        return 10.0 / (7.0 * math.pi * h * h)
    return 1.0 / (math.pi * h * h * h)


@nb.njit(inline="always", cache=True)
def normalisation_inverse(inv_h: float, dim: int) -> float:
    """``alpha_D`` of eq 20 from ``1/h`` (no division: the pair loops' form)."""
    if dim == 1:
        return (2.0 / 3.0) * inv_h
    if dim == 2:
        return (10.0 / (7.0 * math.pi)) * inv_h * inv_h
    return (1.0 / math.pi) * inv_h * inv_h * inv_h


@nb.njit(inline="always", cache=True)
def cubic_spline_shape(q: float) -> float:
    """The shape of eq 20 without its constant: ``W(q, h) / alpha_D`` for ``q = r/h``
    (1 at ``q = 0``, 0 from ``q = 2`` on).  Ratios of kernel values at one ``h``, such as the
    artificial stress's weight ``W(r_ij) / W(dx)``, need only this."""
    if q >= 2.0:
        return 0.0
    if q <= 1.0:
        return 1.0 - 1.5 * q * q + 0.75 * q * q * q
    t = 2.0 - q
    return 0.25 * t * t * t


@nb.njit(inline="always", cache=True)
def cubic_spline(r: float, h: float, dim: int) -> float:
    """Kernel value ``W(r, h)`` (eq 20)."""
    q = r / h
    if q >= 2.0:
        return 0.0
    if q <= 1.0:
        f = 1.0 - 1.5 * q * q + 0.75 * q * q * q
    else:
        t = 2.0 - q
        f = 0.25 * t * t * t
    return normalisation(h, dim) * f


@nb.njit(inline="always", cache=True)
def cubic_spline_dwdr_q(q: float, inv_h: float, dim: int) -> float:
    """``dW/dr`` of eq 20 from ``q = r/h`` and ``1/h`` (no division: the pair loops' form)."""
    if q >= 2.0:
        return 0.0
    if q <= 1.0:
        df = -3.0 * q + 2.25 * q * q
    else:
        t = 2.0 - q
        df = -0.75 * t * t
    return normalisation_inverse(inv_h, dim) * df * inv_h


@nb.njit(inline="always", cache=True)
def cubic_spline_gradient_factor(q: float, inv_h: float, dim: int) -> float:
    """``(dW/dr) / r`` for ``q = r/h < 2``, so that ``grad W_ij = factor * r_ij``.

    The pair loops' form: the inner branch (``q <= 1``, most pairs) needs no division."""
    if q <= 1.0:
        df_over_q = -3.0 + 2.25 * q
    else:
        t = 2.0 - q
        df_over_q = -0.75 * t * t / q
    return normalisation_inverse(inv_h, dim) * df_over_q * inv_h * inv_h


@nb.njit(inline="always", cache=True)
def cubic_spline_dwdr(r: float, h: float, dim: int) -> float:
    """Radial derivative ``dW/dr`` of eq 20 (non-positive)."""
    return cubic_spline_dwdr_q(r / h, 1.0 / h, dim)


@nb.njit(cache=True)
def _kernel_values(r, h, dim):
    out = np.empty_like(r)
    for k in range(r.shape[0]):
        out[k] = cubic_spline(r[k], h, dim)
    return out


@nb.njit(cache=True)
def _kernel_derivatives(r, h, dim):
    out = np.empty_like(r)
    for k in range(r.shape[0]):
        out[k] = cubic_spline_dwdr(r[k], h, dim)
    return out


def kernel(r: np.ndarray, h: float, dim: int) -> np.ndarray:
    """Vectorised ``W(r, h)`` for analysis and tests."""
    r = np.ascontiguousarray(r, dtype=np.float64).ravel()
    return _kernel_values(r, float(h), int(dim))


def kernel_derivative(r: np.ndarray, h: float, dim: int) -> np.ndarray:
    """Vectorised ``dW/dr`` for analysis and tests."""
    r = np.ascontiguousarray(r, dtype=np.float64).ravel()
    return _kernel_derivatives(r, float(h), int(dim))


def gradient_moment(h_over_dx: float, dim: int) -> float:
    """Discrete first moment ``-sum_j V_j (x_j^2 / r_j) dW/dr`` of the kernel gradient over a
    regular lattice of spacing ``dx``: the factor by which the SPH gradient of a linear field
    differs from the exact one.  It is 1 for the continuous kernel and depends on ``h/dx``
    only, so long elastic waves travel at ``moment * c`` whatever the resolution (1D:
    1.022 at ``h = 1.2 dx``, 1 at ``h = dx`` and ``2 dx``)."""
    grid, r = _lattice_neighbours(h_over_dx, dim)
    return float(np.sum(_moment_terms(grid, r, h_over_dx, dim)))


def _lattice_neighbours(h_over_dx: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """The offsets (in spacings) of a regular lattice's points within the support ``2 h``
    of a point, the point itself left out, and their distances."""
    reach = int(np.ceil(2.0 * h_over_dx)) + 1
    axis = np.arange(-reach, reach + 1, dtype=np.float64)
    grid = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    r = np.linalg.norm(grid, axis=1)
    inside = (r > 0) & (r < 2.0 * h_over_dx)
    return grid[inside], r[inside]


def _moment_terms(grid: np.ndarray, r: np.ndarray, h_over_dx: float, dim: int) -> np.ndarray:
    """Each neighbour's term ``-V_j (x_j^2 / r_j) dW/dr`` of :func:`gradient_moment`."""
    return -grid[:, 0] ** 2 / r * kernel_derivative(r, h_over_dx, dim)


def artificial_stress_moment(h_over_dx: float, dim: int, exponent: float = 4.0) -> float:
    """The moment of :func:`gradient_moment` weighted by the artificial stress's ``f_j^n =
    (W(r_j) / W(dx))^n`` (docs/stabilisation.md): for a long wave on a regular lattice, the
    artificial-stress sum of a linearly varying ``R`` is ``M_f rho grad R``, where the stress
    term gives ``M rho grad A`` (1D at ``h = 1.3 dx``: ``M_f`` = 0.770 against ``M`` = 1.022;
    2D: 0.415 against 1.011)."""
    grid, r = _lattice_neighbours(h_over_dx, dim)
    shape = np.vectorize(getattr(cubic_spline_shape, "py_func", cubic_spline_shape))
    f = (shape(r / h_over_dx) / shape(1.0 / h_over_dx)) ** exponent
    return float(np.sum(_moment_terms(grid, r, h_over_dx, dim) * f))
