"""The velocity jump that a reconstructing viscosity sees (``viscosity.scheme =
"reconstruction"``; docs/dissipation.md).

Monaghan's ``Pi_ij`` (eq 29) acts on the jump ``v_ij . r_ij`` between two particles' own
velocities, which is not zero in a smooth flow: a uniform compression ``v = A x`` gives
``v_ij . r_ij = r_ij . A r_ij`` for every pair, so the viscosity heats a flow that has no
shock.  Rosswog (2020, MNRAS 498:4230, "The Lagrangian hydrodynamics code MAGMA2", section
2.3) and, before him, Frontiere, Raskin & Owen (2017, J. Comput. Phys. 332:160, section 2.4)
take the jump between the two velocities *reconstructed* to the pair's midpoint with each
particle's velocity gradient ``L = dv/dx`` and a slope limiter::

    v_i* = v_i - 1/2 Phi_ij L_i r_ij,    v_j* = v_j + 1/2 Phi_ij L_j r_ij      (r_ij = x_i - x_j)
    v_ij* . r_ij = v_ij . r_ij - 1/2 Phi_ij (s_i + s_j),   s = r_ij . L r_ij (m^2/s)

with, by default, van Leer's limiter on the ratio of the two projected slopes ``A_ij = s_i / s_j``,
``Phi_ij = max(0, min(1, 4 A_ij / (1 + A_ij)^2))`` (Rosswog's eq 23; the same function of
``s_j / s_i``, so symmetric in ``i, j``).  Written out, ``1/2 Phi_ij (s_i + s_j) = 2 s_i s_j
/ (s_i + s_j)`` where the slopes agree in sign (their harmonic mean) and 0 where they do not:
for a linear field (``s_i = s_j = v_ij . r_ij``) the reconstructed jump is zero, across a
discontinuity (one slope far larger than the other, or of the other sign) it is the
particles' own.

Two choices are ours, both so that the scheme keeps what Monaghan's has (docs/dissipation.md):

- **Bounded by the unreconstructed jump.** The jump used is ``max(v_ij . r_ij, min(v_ij* .
  r_ij, 0))``: between the particles' own jump and zero for an approaching pair, zero for a
  receding one.  So ``0 <= Pi_ij* <= Pi_ij``: the reconstruction only ever removes viscosity,
  and the heating ``1/2 m_j Pi_ij* v_ij . grad W_ij`` (with the particles' own ``v_ij``, the
  work of the pair force: the energy balance stays exact) is never negative.  Rosswog and
  Spheral use ``v_ij*`` as it comes, which can make a receding pair viscous.
- **The limiter is an option** (``viscosity.limiter``): van Leer's (Rosswog's) or minmod,
  which takes the smaller slope and so leaves more viscosity where the two slopes differ.
  On the bars' elastic front, which is smooth on the particle scale, van Leer's leaves a
  ringing that grows as the spacing falls; minmod's stays bounded (docs/dissipation.md).
- **No near-pair restoration.** Both restore the full viscosity for pairs closer than a
  fraction of the spacing (``Phi *= exp(-((eta - eta_c)/eta_f)^2)``), against gas particles
  interpenetrating; not built here (solids keep their spacing; measured without it).

``v_ij*`` is antisymmetric in ``i, j`` (``Phi_ij`` symmetric), so ``Pi_ij*`` is symmetric and
the pair force antisymmetric: momentum is kept to round-off.  The gradients ``L`` come from a
pass before the pair pass (:func:`impactsph.physics.passes.velocity_gradient_record`), with
the kernel gradient correction so that a linear field's is exact.  Spheral's own variant
(``LimitedMonaghanGingoldViscosity``) takes the whole step ``Phi L r_ij`` rather than half of
it, which reverses a linear field's jump instead of cancelling it.
"""

from __future__ import annotations

import numba as nb

#: ``viscosity.limiter`` -> the code the pair loop receives in ``visc_params[3]``
LIMITERS = {"van_leer": 0.0, "minmod": 1.0}


@nb.njit(inline="always", cache=True)
def limited_slope(slope_i: float, slope_j: float, limiter: float = 0.0) -> float:
    """``1/2 Phi_ij (s_i + s_j)`` (m^2/s): the part of the pair's jump that the two slopes
    ``s_i``, ``s_j`` explain, 0 where they disagree in sign (``s_i s_j <= 0``), else

    - ``limiter = 0`` (``"van_leer"``): ``Phi = 4 A / (1 + A)^2``, ``A = s_i / s_j`` (Rosswog
      2020 eq 23), i.e. the harmonic mean ``2 s_i s_j / (s_i + s_j)``;
    - ``limiter = 1`` (``"minmod"``): the smaller slope, ``sign(s_i) min(|s_i|, |s_j|)``
      (Roe's minmod, the most dissipative of the second-order TVD limiters: it lies between
      half the harmonic mean and the harmonic mean, so it removes less viscosity).

    Written without a division by zero and without a branch (the pair loop vectorises)."""
    product = slope_i * slope_j
    agree = product > 0.0
    denominator = slope_i + slope_j if agree else 1.0
    harmonic = 2.0 * product / denominator
    smaller = min(abs(slope_i), abs(slope_j))
    minmod = smaller if slope_i > 0.0 else -smaller
    chosen = minmod if limiter > 0.5 else harmonic
    return chosen if agree else 0.0


@nb.njit(inline="always", cache=True)
def reconstructed_approach(vr: float, slope_i: float, slope_j: float,
                           limiter: float = 0.0) -> float:
    """The jump ``v_ij . r_ij`` (m^2/s) the viscosity takes for a pair whose own jump is
    ``vr`` and whose projected slopes are ``s_i = r_ij . L_i r_ij``, ``s_j``: the midpoint
    reconstruction's ``vr - limited_slope(s_i, s_j, limiter)``, bounded to ``[vr, 0]`` for an
    approaching pair (``vr < 0``) and not negative for a receding one (then the viscosity
    is zero)."""
    return max(vr, min(vr - limited_slope(slope_i, slope_j, limiter), 0.0))
