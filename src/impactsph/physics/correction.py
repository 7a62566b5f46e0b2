"""Acceleration correction (AC) of Shaw & Reid (paper section 4, eqs 31-37, NOTES 8).

The artificial viscosity is evaluated with fixed parameters (1, 1)::

    u_i = -sum_j m_j Pi^(1,1)_ij grad W_ij                                   (eq 32)

and a smoothed copy of it is subtracted from the acceleration (eqs 33-36)::

    a_i = a_bar_i + u_i - u_corr_i,     u_corr_i = sum_j w_ij (u_i + u_j) / 2

where the weights use the cubic spline ``Wc_ij = W(r_ij, h_c)`` with ``h_c = h/2`` (eq 34,
section 4.1), so that only nearest neighbours contribute.  Eq 34 as printed has no volume
factor and is not dimensionally consistent; the consistent readings are the variants below
(named after NOTES 8 a-c):

- ``volume_weighted`` (a): ``w_ij = V_j Wc_ij``, ``j`` over all particles within ``2 h_c``,
  ``i`` itself included.  A uniform ``u`` keeps ``(1 - sum_j w_ij) u``; at ``h = 1.2 dx`` the
  sum exceeds one (the self weight alone is ``Wc(0) dx^dim``), so the net is anti-viscous.
- ``shepard`` (b): the weights of (a) normalised to sum to one (a convex combination).  A
  uniform ``u`` is removed exactly; what survives is ``(u_i - <u>_i) / 2``.
- ``neighbours_only`` (c): (a) with ``i`` left out; the correction is a few percent of ``u``.

:func:`surviving_fraction` gives ``1 - sum of weights`` on a uniform lattice for each.

Energy (eq 37).  The correction force ``-m_i u_corr_i`` is not antisymmetric in ``i, j``, so it
does not conserve linear momentum, and its work ``-sum_i m_i v_i . u_corr_i`` cannot be written
with relative velocities: any pairwise form ``sum_j w_ij v_ij . (...)`` with symmetric
``m_i w_ij`` sums to zero over the particles and leaves the work unbooked.  The correction that
accounts for the work exactly is therefore ``de_i/dt += v_i . u_corr_i`` (``work``, the
default; it depends on the frame exactly as much as the momentum drift does).  The printed
eq 37, with its index typo mended (``W_ik`` -> ``Wc_ij``), reads
``de_i/dt += 1/2 sum_j w_ij v_ij . u_j`` (``paper``); ``none`` adds nothing.  Each run reports
its total-energy error and the correction's work, so the choice is visible.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ..kernels import cubic_spline

VOLUME_WEIGHTED, SHEPARD, NEIGHBOURS_ONLY = 0, 1, 2
VARIANTS = {"volume_weighted": VOLUME_WEIGHTED, "shepard": SHEPARD,
            "neighbours_only": NEIGHBOURS_ONLY}
ENERGY_WORK, ENERGY_PAPER, ENERGY_NONE = 0, 1, 2
ENERGY_CORRECTIONS = {"work": ENERGY_WORK, "paper": ENERGY_PAPER, "none": ENERGY_NONE}


@nb.njit(inline="always", cache=True)
def correction_weight(volume_j: float, r: float, h_c: float, dim: int) -> float:
    """``w_ij = V_j W(r_ij, h_c)`` before any normalisation."""
    return volume_j * cubic_spline(r, h_c, dim)


@nb.njit(inline="always", cache=True)
def corrected_viscous_acceleration(u_i: float, self_weight: float, weight_sum: float,
                                   weighted_u: float, variant: int) -> float:
    """One component of ``u_i - u_corr_i`` from the sums over the neighbours ``j != i``:
    ``weight_sum = sum_j w_ij`` and ``weighted_u = sum_j w_ij u_j``; ``self_weight = w_ii``."""
    if variant == NEIGHBOURS_ONLY:
        return u_i - 0.5 * (u_i * weight_sum + weighted_u)
    total = weight_sum + self_weight
    u_corr = 0.5 * (u_i * total + weighted_u + self_weight * u_i)
    if variant == SHEPARD:
        u_corr /= total
    return u_i - u_corr


@nb.njit(inline="always", cache=True)
def correction_energy_rate(work: float, paper_sum: float, weight_sum: float,
                           self_weight: float, variant: int, energy_mode: int) -> float:
    """The specific-energy rate that goes with the correction: ``work = -v_i . (dv/dt)_corr``
    (``energy_correction = "work"``), eq 37's ``paper_sum = 1/2 sum_j w_ij v_ij . u_j``
    (``"paper"``; normalised by the weights for the Shepard reading) or nothing."""
    if energy_mode == ENERGY_WORK:
        return work
    if energy_mode == ENERGY_PAPER:
        if variant == SHEPARD:
            return paper_sum / (weight_sum + self_weight)
        return paper_sum
    return 0.0


def surviving_fraction(variant: str, dim: int, h_over_dx: float = 1.2,
                       h_ratio: float = 0.5) -> float:
    """``1 - sum of weights``: the fraction of a uniform viscous acceleration that survives
    the correction in a regular lattice (1 = no correction, 0 = all removed, < 0 = the
    correction overshoots and the net effect is anti-viscous)."""
    h_c = h_over_dx * h_ratio
    reach = int(np.ceil(2 * h_c)) + 1
    axis = np.arange(-reach, reach + 1, dtype=np.float64)
    grid = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    r = np.linalg.norm(grid, axis=1)
    w = np.array([cubic_spline(x, h_c, dim) for x in r])  # dx = 1, V_j = 1
    if variant == "volume_weighted":
        return float(1.0 - w.sum())
    if variant == "neighbours_only":
        return float(1.0 - w[r > 0].sum())
    if variant == "shepard":
        return 0.0
    raise ValueError(f"unknown correction variant {variant!r}; one of {sorted(VARIANTS)}")
