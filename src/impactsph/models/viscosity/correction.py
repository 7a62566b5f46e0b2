"""Acceleration correction (AC) of Shaw & Reid (paper section 4, eqs 31-37), registered as
``scheme = "ac"``; docs/acceleration-correction.md.

The artificial viscosity is evaluated with fixed parameters (1, 1)::

    u_i = -sum_j m_j Pi^(1,1)_ij grad W_ij                                   (eq 32)

and a smoothed copy of it is subtracted from the acceleration (eqs 33-36)::

    a_i = a_bar_i + u_i - u_corr_i,     u_corr_i = sum_j w_ij (u_i + u_j) / 2

where the weights use the cubic spline ``Wc_ij = W(r_ij, h_c)`` with ``h_c = h/2`` (eq 34,
section 4.1), so that only nearest neighbours contribute.  Eq 34 as printed has no volume
factor and is not dimensionally consistent; the consistent readings are the variants below
(the readings a-c of docs/acceleration-correction.md):

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

import math
from typing import Any, Literal

import numba as nb
import numpy as np
from pydantic import Field

from ...kernels import cubic_spline
from ...physics.records import record_coordinate
from ..registry import VISCOSITY, Parameters, ViscosityScheme
from ..types import NonNegativeFloat, PositiveFloat
from .monaghan import pair_viscosity as monaghan_pair_viscosity

VOLUME_WEIGHTED, SHEPARD, NEIGHBOURS_ONLY = 0, 1, 2
VARIANTS = {"volume_weighted": VOLUME_WEIGHTED, "shepard": SHEPARD,
            "neighbours_only": NEIGHBOURS_ONLY}
ENERGY_WORK, ENERGY_PAPER, ENERGY_NONE = 0, 1, 2
ENERGY_CORRECTIONS = {"work": ENERGY_WORK, "paper": ENERGY_PAPER, "none": ENERGY_NONE}
#: the reading of eq 34 used unless the case says otherwise
DEFAULT_VARIANT = "neighbours_only"


def unit_alpha(scheme: str) -> Any:
    """An ``alpha1`` or ``alpha2`` field of a scheme that evaluates the viscosity with (1, 1)
    (eq 31): accepted and not read, so that a case switched from AV keeps its table (the
    bars' ``--set viscosity.scheme=ac``) without a word."""
    return Field(1.0, description=f"not used by {scheme}, which evaluates the viscosity with "
                 "(1, 1) (eq 31)")


class CorrectionParameters(Parameters):
    """The ``[viscosity]`` fields of the acceleration correction.  ``alpha1`` and ``alpha2``
    are accepted (a case switched from AV to AC keeps its table) but not used: AC evaluates
    the viscosity with (1, 1), eq 31."""

    alpha1: NonNegativeFloat = unit_alpha("AC")
    alpha2: NonNegativeFloat = unit_alpha("AC")
    epsilon: PositiveFloat = Field(0.01, description="epsilon of eq 30")
    correction: Literal["volume_weighted", "shepard", "neighbours_only"] = Field(
        DEFAULT_VARIANT, description="AC reading of eq 34 (readings a, b, c of "
        "docs/acceleration-correction.md)")
    energy_correction: Literal["work", "paper", "none"] = Field(
        "work", description="AC energy term: 'work' books the correction's work exactly, "
        "'paper' is eq 37 with its typo mended, 'none' adds nothing")
    correction_h_ratio: float = Field(
        0.5, gt=0.0, le=1.0, description="h_c / h of the correction kernel (section 4.1: 1/2)")


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


def _lattice_weights(dim: int, h_over_dx: float, h_ratio: float):
    """The correction's weights ``w_ij = V_j Wc(r_ij, h_c)`` on a unit lattice (``dx = 1``,
    ``V_j = 1``) around a particle at the origin, with the lattice offsets."""
    h_c = h_over_dx * h_ratio
    reach = int(np.ceil(2 * h_c)) + 1
    axis = np.arange(-reach, reach + 1, dtype=np.float64)
    grid = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), -1).reshape(-1, dim)
    r = np.linalg.norm(grid, axis=1)
    w = np.array([cubic_spline(x, h_c, dim) for x in r])
    return w, grid, r


def surviving_fraction(variant: str, dim: int, h_over_dx: float = 1.2,
                       h_ratio: float = 0.5, mode: str = "uniform") -> float:
    """The fraction of a viscous acceleration field that survives the correction on a regular
    lattice: ``(u_i - u_corr_i) / u_i`` for ``u_j = u cos(k . r_j)`` (1 = no correction, 0 =
    all removed, < 0 = the correction overshoots and the net effect is anti-viscous).
    ``mode``: ``"uniform"`` (``k = 0``: a smooth field, ``1 - sum of weights`` for the
    unnormalised readings) or ``"2dx"`` (the particle-scale checkerboard ``u_j = u (-1)^(n_1 +
    ... + n_dim)``, the shortest mode of the lattice, which the viscosity must damp)."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown correction variant {variant!r}; one of {sorted(VARIANTS)}")
    if mode not in ("uniform", "2dx"):
        raise ValueError(f"mode = {mode!r}: 'uniform' or '2dx'")
    w, grid, r = _lattice_weights(dim, h_over_dx, h_ratio)
    sign = np.ones_like(r) if mode == "uniform" else (-1.0) ** np.abs(grid).sum(1)
    own = r == 0
    neighbours = w[~own].sum()
    weighted = (w[~own] * sign[~own]).sum()  # sum_j w_ij u_j / u_i
    self_weight = float(w[own].sum())
    if variant == "neighbours_only":
        return float(1.0 - 0.5 * (neighbours + weighted))
    total = neighbours + self_weight
    corr = 0.5 * (total + weighted + self_weight)
    if variant == "shepard":
        corr /= total
    return float(1.0 - corr)


def weight_sum(dim: int, h_over_dx: float = 1.2, h_ratio: float = 0.5) -> tuple[float, float]:
    """``(w_ii, sum_{j != i} w_ij)`` of the correction on a regular lattice."""
    w, _, r = _lattice_weights(dim, h_over_dx, h_ratio)
    return float(w[r == 0].sum()), float(w[r > 0].sum())


#: Eq 31: the viscosity that AC corrects is Monaghan's with (1, 1): Monaghan's registered pair
#: function itself, given ``params = (1, 1, epsilon, unused)``.  One compiled function for every
#: scheme built on Monaghan's, which the pair pass then inlines once
#: (:func:`impactsph.codegen._dispatch`).
pair_viscosity = monaghan_pair_viscosity


@nb.njit(inline="always", cache=True)
def correction_sums(p, P, start, end, indices, X, V, H, VOL, BODY, U, dim, h_ratio, paper):
    """The neighbour sums of eq 34 for the particle at sorted position ``p``, over the
    neighbours ``j != i`` of the same body within ``2 h_c``, ``h_c = h_ratio h_ij``:
    ``(w_ii, sum_j w_ij, sum_j w_ij u_j (three components), 1/2 sum_j w_ij v_ij . u_j)``,
    the last (eq 37's) only where ``paper`` is true, else 0: the other energy corrections
    and the pairwise switch never read it, and on the Taylor bar it was an eighth of the
    pass's time (benchmarks/README.md, "A small step's fixed cost"); the other sums are
    the same to the bit."""
    Pi_ = P[p]
    u0 = u1 = u2 = 0.0
    weight_sum = 0.0
    paper_energy = 0.0
    h_i = Pi_[H]
    self_weight = correction_weight(Pi_[VOL], 0.0, h_ratio * h_i, dim)
    for k in range(start, end):
        j = indices[k]
        Pj = P[j]
        # distance first: most neighbours lie beyond 2 h_c, and position and h share the
        # record's first cache line
        h_c = h_ratio * 0.5 * (h_i + Pj[H])
        r2 = 0.0
        for a in range(dim):
            d = record_coordinate(P, p, X, a, dim) - record_coordinate(P, j, X, a, dim)
            r2 += d * d
        if r2 >= 4.0 * h_c * h_c or Pj[BODY] != Pi_[BODY]:
            continue
        w = correction_weight(Pj[VOL], math.sqrt(r2), h_c, dim)
        weight_sum += w
        u0 += w * Pj[U]
        if dim > 1:
            u1 += w * Pj[U + 1]
        if dim > 2:
            u2 += w * Pj[U + 2]
        if paper:
            for a in range(dim):
                paper_energy += 0.5 * w * (Pi_[V + a] - Pj[V + a]) * Pj[U + a]
    return self_weight, weight_sum, u0, u1, u2, paper_energy


@nb.njit(inline="always", cache=True)
def correct(p, i, P, start, end, indices, layout, dim, params, books, dv, de):
    """The correction of the active particle ``i`` at sorted position ``p`` (eqs 33-37):
    ``-u_corr_i`` and its energy term added to the totals ``dv[i]``, ``de[i]``, and for the
    run's books its power per unit mass ``v_i . a_c`` (``a_c`` the acceleration it adds) and
    its energy term (W/kg) into ``books[i, 0]``, ``books[i, 1]``.  Reads the packed records
    ``P`` (columns ``layout = (x, v, h, volume, body, u)``:
    :func:`impactsph.physics.passes.record_columns`), whose ``u`` the pair pass (evaluated
    with (1, 1)) has filled; neighbours of the same body within
    ``2 h_c``, ``h_c = h_ratio h``.  ``params = (h_ratio, variant, energy mode, unused)``."""
    X, V, H, VOL, BODY, U = layout
    variant = int(params[1])
    energy_mode = int(params[2])
    Pi_ = P[p]
    self_weight, weight_sum, u0, u1, u2, paper_energy = correction_sums(
        p, P, start, end, indices, X, V, H, VOL, BODY, U, dim, params[0],
        energy_mode == ENERGY_PAPER)
    weighted_u = (u0, u1, u2)
    work = 0.0
    for a in range(dim):
        net = corrected_viscous_acceleration(Pi_[U + a], self_weight, weight_sum,
                                             weighted_u[a], variant)
        change = net - Pi_[U + a]
        work -= Pi_[V + a] * change
        dv[i, a] += change
    heating = correction_energy_rate(work, paper_energy, weight_sum, self_weight, variant,
                                     energy_mode)
    de[i] += heating
    books[i, 0] = -work
    books[i, 1] = heating


ACCELERATION_CORRECTION = VISCOSITY.register(ViscosityScheme(
    name="ac", pair_viscosity=pair_viscosity, parameters=CorrectionParameters,
    pair_parameters=lambda v: (1.0, 1.0, float(v.epsilon), 0.0),
    correction=correct,
    correction_parameters=lambda v: (float(v.correction_h_ratio),
                                     float(VARIANTS[v.correction]),
                                     float(ENERGY_CORRECTIONS[v.energy_correction]), 0.0),
    # the correction kernel's support 2 h_c = h_ratio 2 h_ij: the inner list suffices
    correction_reach=lambda v: float(v.correction_h_ratio),
    source="Shaw & Reid (2009) eqs 31-37",
    description="Shaw-Reid acceleration correction of Monaghan's viscosity (1, 1)"))
