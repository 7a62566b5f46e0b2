"""Viscosity switches: Monaghan's viscosity with each pair's ``Pi_ij`` multiplied by the mean
``(f_i + f_j) / 2`` of a per-particle factor ``f`` in ``[0, 1]`` (docs/dissipation.md).

A symmetric factor keeps the pair force ``m_i m_j Pi_ij f_ij grad W_ij`` antisymmetric, so
linear momentum is kept to round-off, and the heating ``1/2 m_j Pi_ij f_ij v_ij . grad W_ij``
is still the pair force's work, so the total energy is kept; ``Pi_ij f_ij >= 0`` for an
approaching pair, so a switch never makes the viscosity anti-dissipative.

The factor is set after each rate evaluation from that evaluation's fields and used in the
next one (half a time step later, with the midpoint integrator); it starts at 1 (the full
viscosity) and is a per-particle array of the state (``ParticleState.viscosity_factor``,
written to checkpoints and snapshots).  Five switches are registered:

- ``balsara``: Balsara (1995, J. Comput. Phys. 121:357-372, eq 4.1)::

      f_i = |div v|_i / (|div v|_i + |curl v|_i + eps_B c_i / h_i)

  with the SPH estimates ``div v_i = -sum_j V_j v_ij . grad W_ij`` and ``curl v_i = -sum_j
  V_j grad W_ij x v_ij`` (neighbours of the same body).  The viscosity stays on in
  compression and expansion and is switched off in shear and rotation, where Monaghan's
  ``Pi_ij`` heats a solid that should not be heated (the foot of a Taylor bar).
  ``eps_B`` = ``balsara_epsilon`` (Balsara's 1e-4) keeps the denominator positive.

- ``morris_monaghan``: Morris & Monaghan (1997, J. Comput. Phys. 136:41-50) with the source
  term of Rosswog et al. (2000, MNRAS 317:443): each particle's linear coefficient
  ``alpha_i = f_i alpha1`` (and quadratic ``f_i alpha2``) evolves as::

      d alpha_i/dt = -(alpha_i - alpha_min) / tau_i + max(-div v_i, 0) (alpha1 - alpha_i)

  with ``tau_i = h_i / (l c_i)``: it rises towards ``alpha1`` where the flow converges (a
  shock) and decays to ``alpha_min`` in ``tau`` elsewhere; it starts at ``alpha_min`` (as
  Morris & Monaghan start it).  Between two rate evaluations the
  equation is solved exactly with the coefficients of the later one (unconditionally stable,
  first order in time).

- ``cullen_dehnen``: Cullen & Dehnen (2010, MNRAS 408:669, section 3): a target
  ``f_loc = H^2 A / (v_sig^2 + H^2 A)`` from the shock indicator ``A = xi max(-dD/dt, 0)`` (the
  rate at which the flow *starts* to converge, ``D = div v``), limited in shear by ``xi =
  |2 (1 - R)^4 D|^2 / (|2 (1 - R)^4 D|^2 + tr(S S^T))`` (``S`` the traceless symmetric
  velocity gradient, ``R`` the kernel-weighted sign of the neighbours' divergence); the
  factor jumps up to ``f_loc`` and decays to it in ``H / (2 l v_sig)``, ``l = 0.05``.  ``H`` is
  their smoothing length, the kernel's support: ``2 h`` here.  Where they compute ``dD/dt``
  from the gradient of the acceleration, this takes the change of ``D`` since the last rate
  evaluation (kept in the switch's memory), as SWIFT and GADGET-4 do; ``R`` uses the
  neighbours' kept divergences.  The factor starts at 1.

- ``ac_pairwise``: the acceleration correction of Shaw & Reid (2009, eqs 31-36) turned into
  a factor.  From the unscaled viscous acceleration ``u_i`` (eq 32, (1, 1)) and the paper's
  correction ``u_corr_i`` (eq 34, in the reading and width the case chooses, as for
  ``scheme = "ac"``), the fraction of ``u_i`` that the correction leaves, along ``u_i``::

      f_i = clip(u_i . (u_i - u_corr_i) / |u_i|^2, 0, 1)      (f_i = 1 where u_i = 0)

  Where AC is a mild correction this is AC's surviving fraction; where AC's correction would
  exceed the viscosity itself (an anti-viscous net, the cause of the 3D blow-ups in
  docs/validation.md) the factor stops at 0.  The correction force of ``scheme = "ac"`` is
  not antisymmetric (its momentum drift: docs/acceleration-correction.md); this one is.
"""

from __future__ import annotations

import math
from typing import Literal

import numba as nb
from pydantic import Field

from ...kernels import cubic_spline, cubic_spline_gradient_factor
from ...physics.records import record_coordinate
from ..registry import VISCOSITY, Parameters, ViscosityScheme
from ..types import NonNegativeFloat, PositiveFloat
from .correction import (
    DEFAULT_VARIANT,
    VARIANTS,
    CorrectionParameters,
    corrected_viscous_acceleration,
    correction_sums,
    unit_alpha,
)
from .correction import pair_viscosity as unit_viscosity
from .monaghan import MonaghanParameters
from .monaghan import pair_viscosity as monaghan_pair


class BalsaraParameters(MonaghanParameters):
    """The ``[viscosity]`` fields of Monaghan's viscosity with Balsara's switch."""

    balsara_epsilon: PositiveFloat = Field(
        1e-4, description="eps_B of Balsara's switch: the floor eps_B c/h of its denominator")


@nb.njit(inline="always", cache=True)
def neighbour_fields(p, P, start, end, indices, X, V, H, VOL, BODY, C, MEMORY, M, dim):
    """One loop over the neighbours of the same body of the particle at sorted position
    ``p``: the SPH velocity gradient ``L_ab = dv_a/dx_b = -sum_j V_j v_ij,a dW_ij/dx_b``
    (``grad W`` with the pair's mean smoothing length; nine components, row by row), ``rho_i
    R = sum_j sign(D_j) m_j W_ij`` (``j = i`` included, ``D_j`` the divergences the switch kept
    at the last evaluation) and ``v_sig = max_j (c_ij - min(0, v_ij . r_ij / |r_ij|))`` (``c_i``
    at least).

    Written as the pair pass's first loop (:func:`impactsph.physics.passes.particle_rates`),
    so that LLVM vectorises it under the switch pass's flags (``SWITCH_FASTMATH``): no branch
    (a pair outside the support, or of another body, is a mask, ``fq = 0``, its terms exactly
    zero), the neighbour's columns read as ``P[j, col]``, no zero-division checks."""
    h_i = P[p, H]
    body_i = P[p, BODY]
    c_i = P[p, C]
    xi0 = record_coordinate(P, p, X, 0, dim)
    xi1 = record_coordinate(P, p, X, 1, dim) if dim > 1 else 0.0
    xi2 = record_coordinate(P, p, X, 2, dim) if dim > 2 else 0.0
    vi0 = P[p, V]
    vi1 = P[p, V + 1] if dim > 1 else 0.0
    vi2 = P[p, V + 2] if dim > 2 else 0.0
    L00 = L01 = L02 = L10 = L11 = L12 = L20 = L21 = L22 = 0.0
    memory_i = P[p, MEMORY]
    sign_i = 1.0 if memory_i > 0.0 else (-1.0 if memory_i < 0.0 else 0.0)
    R = sign_i * P[p, M] * cubic_spline(0.0, h_i, dim)
    v_sig = c_i
    for k in range(start, end):
        j = indices[k]  # P[j, col], not a row view: the view stops the vectoriser
        d0 = xi0 - record_coordinate(P, j, X, 0, dim)
        d1 = xi1 - record_coordinate(P, j, X, 1, dim) if dim > 1 else 0.0
        d2 = xi2 - record_coordinate(P, j, X, 2, dim) if dim > 2 else 0.0
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        h_ij = 0.5 * (h_i + P[j, H])
        inv_h = 1.0 / h_ij
        q2 = r2 * inv_h * inv_h
        inside = (q2 < 4.0) & (r2 > 0.0) & (P[j, BODY] == body_i)
        r = math.sqrt(r2)
        fq = P[j, VOL] * cubic_spline_gradient_factor(math.sqrt(q2), inv_h, dim) if inside \
            else 0.0
        g0, g1, g2 = fq * d0, fq * d1, fq * d2
        u0 = vi0 - P[j, V]
        u1 = vi1 - P[j, V + 1] if dim > 1 else 0.0
        u2 = vi2 - P[j, V + 2] if dim > 2 else 0.0
        L00 -= u0 * g0
        L01 -= u0 * g1
        L02 -= u0 * g2
        L10 -= u1 * g0
        L11 -= u1 * g1
        L12 -= u1 * g2
        L20 -= u2 * g0
        L21 -= u2 * g1
        L22 -= u2 * g2
        mj = P[j, MEMORY]
        sign_j = 1.0 if mj > 0.0 else (-1.0 if mj < 0.0 else 0.0)
        R += sign_j * P[j, M] * cubic_spline(r, h_ij, dim) if inside else 0.0
        approach = (u0 * d0 + u1 * d1 + u2 * d2) / r if inside else 0.0
        v_sig = max(v_sig, 0.5 * (c_i + P[j, C]) - min(0.0, approach)) if inside else v_sig
    return L00, L01, L02, L10, L11, L12, L20, L21, L22, R, v_sig


@nb.njit(inline="always", cache=True)
def cullen_dehnen_fields(p, P, start, end, indices, X, V, H, VOL, BODY, C, MEMORY, RHO, M, dim):
    """``(div v, tr(S S^T), R, v_sig)`` of the particle at sorted position ``p`` from
    :func:`neighbour_fields`: the divergence, the squared norm of the velocity gradient's
    traceless symmetric part ``S`` and ``R`` divided by ``rho_i``."""
    L00, L01, L02, L10, L11, L12, L20, L21, L22, R, v_sig = neighbour_fields(
        p, P, start, end, indices, X, V, H, VOL, BODY, C, MEMORY, M, dim)
    div = L00 + L11 + L22
    third = div / dim
    s00, s11, s22 = L00 - third, L11 - third, L22 - third
    if dim < 3:
        s22 = 0.0
    if dim < 2:
        s11 = 0.0
    s01, s02, s12 = 0.5 * (L01 + L10), 0.5 * (L02 + L20), 0.5 * (L12 + L21)
    shear = s00 * s00 + s11 * s11 + s22 * s22 + 2.0 * (s01 * s01 + s02 * s02 + s12 * s12)
    return div, shear, R / P[p, RHO], v_sig


@nb.njit(inline="always", cache=True)
def divergence_and_curl(p, P, start, end, indices, layout, dim):
    """``(div v, |curl v|)`` of the particle at sorted position ``p``, from the velocity
    gradient of :func:`neighbour_fields`."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    L00, L01, L02, L10, L11, L12, L20, L21, L22, _, _ = neighbour_fields(
        p, P, start, end, indices, X, V, H, VOL, BODY, C, MEMORY, M, dim)
    c0, c1, c2 = L21 - L12, L02 - L20, L10 - L01
    return L00 + L11 + L22, math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


@nb.njit(inline="always", cache=True)
def balsara_factor(p, i, P, start, end, indices, layout, dim, params, elapsed, memory):
    """Balsara's ``f_i`` for the particle at sorted position ``p`` (``params = (eps_B, unused,
    unused, unused)``; ``layout``: :class:`~impactsph.models.registry.ViscosityScheme`)."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    memory[i] = 0.0  # nothing kept
    div, curl = divergence_and_curl(p, P, start, end, indices, layout, dim)
    a = abs(div)
    return a / (a + curl + params[0] * P[p, C] / P[p, H])


class MorrisMonaghanParameters(MonaghanParameters):
    """The ``[viscosity]`` fields of Morris & Monaghan's time-dependent viscosity: ``alpha1``
    and ``alpha2`` are the coefficients at the largest factor (1)."""

    alpha_min: NonNegativeFloat = Field(
        0.1, description="the linear coefficient the viscosity decays to away from "
        "compression (Morris & Monaghan 1997: 0.1); the factor's floor is alpha_min/alpha1")
    decay: PositiveFloat = Field(
        0.2, description="l of the decay time tau = h / (l c) (Morris & Monaghan 1997: "
        "0.1-0.2)")


@nb.njit(inline="always", cache=True)
def morris_monaghan_factor(p, i, P, start, end, indices, layout, dim, params, elapsed, memory):
    """Morris & Monaghan's ``f_i = alpha_i / alpha1`` after ``elapsed`` seconds (``params =
    (alpha_min / alpha1, l, unused, unused)``): the factor in use (record column ``f``)
    advanced by the exact solution of ``df/dt = -(f - f_min) / tau + S (1 - f)`` with this
    evaluation's ``tau = h / (l c)`` and ``S = max(-div v, 0)``."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    memory[i] = 0.0  # nothing kept
    div, _ = divergence_and_curl(p, P, start, end, indices, layout, dim)
    f_min = params[0]
    rate = params[1] * P[p, C] / P[p, H]  # 1 / tau
    source = max(-div, 0.0)
    k = rate + source
    f_eq = (f_min * rate + source) / k
    return f_eq + (P[p, F] - f_eq) * math.exp(-k * elapsed)


class PairwiseCorrectionParameters(CorrectionParameters):
    """The ``[viscosity]`` fields of the pairwise acceleration correction: those of
    ``scheme = "ac"`` (``energy_correction`` is not used: the pairwise form books its heating
    exactly)."""


@nb.njit(inline="always", cache=True)
def ac_pairwise_factor(p, i, P, start, end, indices, layout, dim, params, elapsed, memory):
    """The pairwise AC's ``f_i`` (``params = (h_ratio, variant, unused, unused)``)."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    memory[i] = 0.0  # nothing kept
    Pi_ = P[p]
    self_weight, weight_sum, s0, s1, s2, _ = correction_sums(
        p, P, start, end, indices, X, V, H, VOL, BODY, U, dim, params[0], False)
    variant = int(params[1])
    weighted = (s0, s1, s2)
    uu = 0.0
    un = 0.0
    for a in range(dim):
        u = Pi_[U + a]
        uu += u * u
        un += u * corrected_viscous_acceleration(u, self_weight, weight_sum, weighted[a],
                                                 variant)
    if uu == 0.0:
        return 1.0
    return min(max(un / uu, 0.0), 1.0)


class OptimisedCorrectionParameters(Parameters):
    """The ``[viscosity]`` fields of the optimised correction."""

    alpha1: NonNegativeFloat = unit_alpha("ac_optimised")
    alpha2: NonNegativeFloat = unit_alpha("ac_optimised")
    epsilon: PositiveFloat = Field(0.01, description="epsilon of eq 30")
    correction: Literal["volume_weighted", "shepard", "neighbours_only"] = Field(
        DEFAULT_VARIANT, description="the reading of eq 34 of the bounding correction")
    bound_h_ratio: float = Field(
        1.0, gt=0.0, le=1.0, description="ac_optimised: h_c / h of the correction that bounds "
        "the factor from below (1: h_c = h, docs/dissipation.md)")


#: bisection steps of the optimised correction's factor (its precision: 2^-12 of the range)
OPTIMISED_BISECTIONS = 12


@nb.njit(inline="always", cache=True)
def _variation_slope(p, P, start, end, indices, X, V, H, VOL, BODY, U, F, dim, f, step):
    """``d TV_i / d f`` at ``f``: the slope of the local total variation of the velocity after
    ``step`` seconds of viscous acceleration, ``TV_i(f) = sum_j V_j W_ij |v_ij + step (f u_i -
    f_j u_j)|`` (neighbours of the same body, ``f_j`` their factors in use)."""
    Pi_ = P[p]
    slope = 0.0
    h_i = Pi_[H]
    for k in range(start, end):
        j = indices[k]
        Pj = P[j]
        if Pj[BODY] != Pi_[BODY]:
            continue
        r2 = 0.0
        for a in range(dim):
            d = record_coordinate(P, p, X, a, dim) - record_coordinate(P, j, X, a, dim)
            r2 += d * d
        h_ij = 0.5 * (h_i + Pj[H])
        if r2 >= 4.0 * h_ij * h_ij or r2 == 0.0:
            continue
        w = Pj[VOL] * cubic_spline(math.sqrt(r2), h_ij, dim)
        n2 = 0.0
        dot = 0.0
        for a in range(dim):
            e = Pi_[V + a] - Pj[V + a] + step * (f * Pi_[U + a] - Pj[F] * Pj[U + a])
            n2 += e * e
            dot += e * step * Pi_[U + a]
        if n2 > 0.0:
            slope += w * dot / math.sqrt(n2)
    return slope


@nb.njit(inline="always", cache=True)
def ac_optimised_factor(p, i, P, start, end, indices, layout, dim, params, elapsed, memory):
    """The optimised correction's ``f_i`` (``params = (h_ratio, variant, unused, unused)``):
    the smallest ``f`` in ``[f_AC, 1]`` that minimises ``TV_i(f)`` (see
    :func:`_variation_slope`) over the next ``elapsed`` seconds, ``f_AC`` the pairwise AC's
    factor (:func:`ac_pairwise_factor`).  ``TV_i`` is convex in ``f`` (a sum of norms of
    affine functions), so its slope rises with ``f``: ``f_AC`` where the slope there is not
    negative, 1 where it is negative at 1, else the root of the slope by bisection."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    memory[i] = 0.0  # nothing kept
    low = ac_pairwise_factor(p, i, P, start, end, indices, layout, dim, params, elapsed,
                             memory)
    if elapsed <= 0.0 or low >= 1.0:
        return low
    # one call site of the slope (inlined once): f_AC, then 1, then the bisection
    a, b = low, 1.0
    for step in range(OPTIMISED_BISECTIONS + 2):
        f = low if step == 0 else (1.0 if step == 1 else 0.5 * (a + b))
        slope = _variation_slope(p, P, start, end, indices, X, V, H, VOL, BODY, U, F, dim, f,
                                 elapsed)
        if step == 0:
            if slope >= 0.0:
                return low
        elif step == 1:
            if slope <= 0.0:
                return 1.0
        elif slope < 0.0:
            a = f
        else:
            b = f
    return b


class CullenDehnenParameters(MonaghanParameters):
    """The ``[viscosity]`` fields of Cullen & Dehnen's switch: ``alpha1`` and ``alpha2`` are
    the coefficients at the largest factor (1)."""

    cd_decay: PositiveFloat = Field(
        0.05, description="cullen_dehnen: l of the decay time 2h / (2 l v_sig) (Cullen & "
        "Dehnen 2010: 0.05)")


@nb.njit(inline="always", cache=True)
def cullen_dehnen_factor(p, i, P, start, end, indices, layout, dim, params, elapsed, memory):
    """Cullen & Dehnen's ``f_i = alpha_i / alpha1`` (``params = (l, unused, unused,
    unused)``): the local target ``f_loc = H^2 A / (v_sig^2 + H^2 A)`` with ``A = xi
    max(-dD/dt, 0)``, ``dD/dt`` the change of the divergence since the last evaluation over
    ``elapsed``, ``xi = |2 (1 - R)^4 D|^2 / (|2 (1 - R)^4 D|^2 + tr(S S^T))`` and ``H = 2 h``
    (their smoothing length is the kernel's support); ``f = f_loc`` where the factor in use
    is below it, else it decays towards it, ``f_loc + (f - f_loc) exp(-elapsed 2 l v_sig /
    H)``.  Keeps ``D`` in ``memory[i]``."""
    X, V, H, VOL, BODY, U, C, F, MEMORY, RHO, M = layout
    div, shear, R, v_sig = cullen_dehnen_fields(p, P, start, end, indices, X, V, H, VOL, BODY, C,
                                                MEMORY, RHO, M, dim)
    memory[i] = div
    if elapsed <= 0.0:
        return P[p, F]
    rate = (div - P[p, MEMORY]) / elapsed
    one_r = 1.0 - R
    limiter = 2.0 * one_r * one_r * one_r * one_r * div
    limiter *= limiter
    xi = limiter / (limiter + shear) if limiter + shear > 0.0 else 0.0
    support = 2.0 * P[p, H]
    a = xi * max(-rate, 0.0) * support * support
    f_loc = a / (v_sig * v_sig + a)
    f_old = P[p, F]
    if f_old <= f_loc:
        return f_loc
    return f_loc + (f_old - f_loc) * math.exp(-elapsed * 2.0 * params[0] * v_sig / support)


BALSARA = VISCOSITY.register(ViscosityScheme(
    name="balsara", pair_viscosity=monaghan_pair, parameters=BalsaraParameters,
    pair_parameters=lambda v: (float(v.alpha1), float(v.alpha2), float(v.epsilon), 0.0),
    switch=balsara_factor, switch_vectorises=True,
    switch_parameters=lambda v: (float(v.balsara_epsilon), 0.0, 0.0, 0.0),
    source="Balsara (1995) J Comput Phys 121:357, eq 4.1",
    description="Monaghan's viscosity with Balsara's shear switch"))

def _floor(viscosity) -> float:
    """Morris & Monaghan's ``f_min = alpha_min / alpha1`` (at most 1)."""
    alpha1 = float(viscosity.alpha1)
    return min(float(viscosity.alpha_min) / alpha1, 1.0) if alpha1 > 0 else 1.0


MORRIS_MONAGHAN = VISCOSITY.register(ViscosityScheme(
    name="morris_monaghan", pair_viscosity=monaghan_pair, parameters=MorrisMonaghanParameters,
    pair_parameters=lambda v: (float(v.alpha1), float(v.alpha2), float(v.epsilon), 0.0),
    switch=morris_monaghan_factor, switch_vectorises=True,
    switch_parameters=lambda v: (_floor(v), float(v.decay), 0.0, 0.0),
    initial_factor=lambda v: _floor(v),
    source="Morris & Monaghan (1997) J Comput Phys 136:41; the source term of Rosswog et al. "
           "(2000) MNRAS 317:443",
    description="Monaghan's viscosity with Morris & Monaghan's time-dependent coefficient"))

CULLEN_DEHNEN = VISCOSITY.register(ViscosityScheme(
    name="cullen_dehnen", pair_viscosity=monaghan_pair, parameters=CullenDehnenParameters,
    pair_parameters=lambda v: (float(v.alpha1), float(v.alpha2), float(v.epsilon), 0.0),
    switch=cullen_dehnen_factor,
    switch_parameters=lambda v: (float(v.cd_decay), 0.0, 0.0, 0.0),
    source="Cullen & Dehnen (2010) MNRAS 408:669, section 3 (the time derivative of the "
           "divergence by differences between evaluations)",
    description="Monaghan's viscosity with Cullen & Dehnen's shock indicator and limiter"))

AC_PAIRWISE = VISCOSITY.register(ViscosityScheme(
    name="ac_pairwise", pair_viscosity=unit_viscosity, parameters=PairwiseCorrectionParameters,
    pair_parameters=lambda v: (1.0, 1.0, float(v.epsilon), 0.0),
    switch=ac_pairwise_factor,
    # the correction kernel's support 2 h_c = h_ratio 2 h_ij: the inner list suffices
    switch_reach=lambda v: float(v.correction_h_ratio),
    switch_parameters=lambda v: (float(v.correction_h_ratio), float(VARIANTS[v.correction]),
                                 0.0, 0.0),
    source="Shaw & Reid (2009) eqs 31-36, as a symmetric factor (docs/dissipation.md)",
    description="the acceleration correction as a pairwise, momentum-conserving factor"))

AC_OPTIMISED = VISCOSITY.register(ViscosityScheme(
    name="ac_optimised", pair_viscosity=unit_viscosity,
    parameters=OptimisedCorrectionParameters,
    pair_parameters=lambda v: (1.0, 1.0, float(v.epsilon), 0.0),
    switch=ac_optimised_factor,
    switch_parameters=lambda v: (float(v.bound_h_ratio), float(VARIANTS[v.correction]),
                                 0.0, 0.0),
    source="ours (docs/dissipation.md), in the spirit of Shaw, Roy & Reid (2011) IJSS "
           "48:3484: the correction's strength by a local total variation",
    description="the pairwise correction, each particle's factor chosen to minimise the "
                "local total variation of the velocity"))
