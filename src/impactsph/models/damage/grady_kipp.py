"""Grady-Kipp tensile damage for brittle materials, as in Benz & Asphaug (1995).

**Flaws.** A body of volume ``V`` holds flaws whose number activated at tensile strain ``eps``
follows the Weibull law ``n(eps) = k V eps^m`` (Benz & Asphaug 1995, eq 7; ``k`` in m^-3, the
volume per unit depth in 2D).  The ``j``-th flaw of the body (j = 1, 2, ...) activates at
``eps_j = (j / (k V))^(1/m)``; flaws are dealt to particles at random (in proportion to their
volume) until every particle has at least one (about ``n ln n`` flaws for ``n`` particles).
Each particle keeps its number of flaws ``N``, and the activation strains of its weakest and
strongest, ``eps_min`` and ``eps_max`` (seeded: ``[grady_kipp] seed``, one stream per body,
so a run is reproducible).

**Growth.** The particle's local tensile strain is ``eps = sigma_1 / E`` with ``sigma_1`` the
largest principal stress of the undamaged stress ``-P I + S`` (Benz & Asphaug's
``sigma / ((1 - D) E)`` of the damaged stress; the same).  Where ``eps > eps_min`` its
``n_act`` active flaws grow the damage (Benz & Asphaug 1995, eq 11 and section 3.2)::

    d D^(1/3) / dt = n_act^(1/3) c_g / R_s,      c_g = 0.4 c_l,  R_s = 2 h

with ``c_l = sqrt((K + 4/3 mu)/rho0)`` the longitudinal wave speed, ``crack_speed_fraction``
0.4 (their choice) and ``R_s`` the particle's kernel support radius.  ``n_act`` is the
expected count of the particle's flaws below ``eps``: flaws are uniform in ``eps^m`` (their
index is), so ``n_act = 1 + (N - 1) (eps^m - eps_min^m) / (eps_max^m - eps_min^m)``, at most
``N``.  A particle with one flaw (``n_act = 1``) goes from intact to ``D = 1`` in
``R_s / c_g`` of tension.  ``D`` is capped at 1.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from pydantic import Field

from ..columns import DAMAGE, LONGITUDINAL_SPEED, YOUNGS
from ..registry import DAMAGE as DAMAGE_MODELS
from ..registry import DamageModel, Parameters
from ..types import PositiveFloat

#: own state: number of flaws, weakest and strongest activation strains
FLAWS, WEAKEST, STRONGEST = range(3)


class GradyKippParameters(Parameters):
    """``[materials.X.grady_kipp]``: the Weibull flaw distribution and the crack speed."""

    weibull_coefficient: PositiveFloat = Field(
        description="k of n(eps) = k V eps^m (1/m^3; 1/m^2 per unit depth in 2D)")
    weibull_exponent: PositiveFloat = Field(description="m of n(eps) = k V eps^m")
    crack_speed_fraction: PositiveFloat = Field(
        0.4, le=1.0, description="crack growth speed over the longitudinal wave speed")
    seed: int = Field(0, ge=0, description="seed of the flaws' random assignment")


@nb.njit(inline="always", cache=True)
def largest_principal(a00, a01, a02, a11, a12, a22):
    """The largest eigenvalue of a symmetric 3x3 matrix (the trigonometric solution of the
    characteristic cubic; Smith 1961)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    if p1 <= 1e-30 * (a00 * a00 + a11 * a11 + a22 * a22):
        return max(a00, max(a11, a22))
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
           + a02 * (a01 * a12 - b11 * a02))
    r = det / (2.0 * p * p * p)
    r = min(max(r, -1.0), 1.0)
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi)


@nb.njit(cache=True)
def update(S, pressure, rho, size, dt, plastic_strain_increment, row, params, state, own):
    """Grow ``D^(1/3)`` by ``n_act^(1/3) c_g dt / (2 h)`` where ``sigma_1 / E > eps_min``."""
    damage = state[DAMAGE]
    if damage >= 1.0:
        return
    sigma_1 = largest_principal(S[0, 0] - pressure, S[0, 1], S[0, 2], S[1, 1] - pressure,
                                S[1, 2], S[2, 2] - pressure)
    strain = sigma_1 / row[YOUNGS]
    eps_min = own[WEAKEST]
    if strain <= eps_min:
        return
    flaws = own[FLAWS]
    active = 1.0
    if flaws > 1.0:
        m = params[1]
        lo = eps_min ** m
        hi = own[STRONGEST] ** m
        active = 1.0 + (flaws - 1.0) * (strain ** m - lo) / (hi - lo) if hi > lo else flaws
        active = min(active, flaws)
    growth = params[2] * row[LONGITUDINAL_SPEED] / (2.0 * size)
    root = damage ** (1.0 / 3.0) + dt * growth * active ** (1.0 / 3.0)
    state[DAMAGE] = min(root * root * root, 1.0)


def assign_flaws(parameters: GradyKippParameters, volume: np.ndarray,
                 rng: np.random.Generator) -> np.ndarray:
    """Each particle's ``(N, eps_min, eps_max)``: flaws ``j = 1, 2, ...`` with activation
    strains ``(j / (k V))^(1/m)`` dealt at random, in proportion to volume, until every
    particle has one."""
    n = volume.shape[0]
    out = np.zeros((n, 3))
    if n == 0:
        return out
    total = float(volume.sum())
    p = volume / total
    owners = np.empty(0, dtype=np.int64)
    batch = max(int(n * (math.log(n) + 4.0)) + 16, 64)
    while True:
        owners = np.concatenate([owners, rng.choice(n, size=batch, p=p)])
        seen, first = np.unique(owners, return_index=True)
        if seen.shape[0] == n:
            break
        batch *= 2
    last_needed = int(first.max())  # the flaw that gave the last particle its first
    owners = owners[: last_needed + 1]
    j = np.arange(1, owners.shape[0] + 1, dtype=float)
    strain = (j / (parameters.weibull_coefficient * total)) ** (1.0 / parameters.weibull_exponent)
    out[:, FLAWS] = np.bincount(owners, minlength=n)
    out[:, WEAKEST] = np.full(n, np.inf)
    np.minimum.at(out[:, WEAKEST], owners, strain)
    np.maximum.at(out[:, STRONGEST], owners, strain)
    return out


GRADY_KIPP = DAMAGE_MODELS.register(DamageModel(
    name="grady_kipp", update=update, parameters=GradyKippParameters,
    columns=("weibull_coefficient", "weibull_exponent", "crack_speed_fraction"),
    coefficients=lambda p, constants: (p.weibull_coefficient, p.weibull_exponent,
                                       p.crack_speed_fraction),
    state=("flaws", "weakest_flaw_strain", "strongest_flaw_strain"),
    initial_state=assign_flaws, source="Benz & Asphaug (1995) eqs 7-11",
    description="brittle tensile damage from a Weibull flaw distribution"))
