"""Every compiled pass whose body depends on the registered models: the one place where the
SPH rate equations are applied, for the CPU and for the GPU alike.

This file is a template.  :mod:`impactsph.codegen` copies it, with the *binding* block below
replaced by the dimension ``DIM``, the material-table layout and the dispatch functions of the
registered models (``eos_pressure``, ``strength_return``, ``pair_viscosity``,
``viscosity_correction``: an if-chain over the models' compiled functions), into a module of
its own for each dimension and set of models, and imports that.  So a model is called, and
inlined, where its equation applies, and the dimension is a compile-time constant (the small
loops over components unroll).  The copy is a file, so numba's disk cache keeps its machine
code between runs.  (The package's own copy, with the stub binding, is never run.)

Per particle ``i`` the passes evaluate the right-hand sides of the continuity (eq 22),
momentum (eq 27), energy (eq 28) and Jaumann stress-rate (eq 14) equations:

1. :func:`particle_record` (every row, ghosts included): pressure from the EOS, wave speed,
   ``A = sigma/rho^2``, ``P/rho^2`` and ``V = m/rho`` into the particle's packed record
   (:mod:`.records`), in the neighbour list's cell (Morton) order;
2. :func:`particle_rates` (every active particle; gather, so threads never write the same
   memory and the result does not depend on their number): the sums over its neighbours of
   continuity, velocity gradient, stress and viscous accelerations, stress work and viscous
   heating (one loop without branches, which LLVM vectorises), the contact terms (a second
   loop, only where another body is within reach); then its Jaumann stress rate;
3. ``viscosity_correction`` (a scheme with a correction, e.g. AC): per particle again, after
   every particle's viscous acceleration is known;
4. :func:`advance_particle`: one integrator stage of one particle, and its strength model's
   return map.

The CPU passes (:func:`particle_pass`, :func:`pair_pass`, :func:`correction_pass`,
:func:`stage`) run these bodies over parallel chunks; :func:`cuda_kernels` runs the same
bodies, one CUDA thread per particle.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from impactsph.boundaries import enforce_particle
from impactsph.jitcache import noalias_option
from impactsph.kernels import cubic_spline_gradient_factor, cubic_spline_shape
from impactsph.materials import (
    BULK,
    DAMAGE_KIND,
    EOS_KIND,
    HEAT_PER_WORK,
    RHO0,
    SHEAR,
    STRENGTH_KIND,
    WAVE_MODULUS,
)
from impactsph.models.columns import (
    DAMAGE,
    EQUIVALENT_PLASTIC_STRAIN,
    TEMPERATURE,
    THICKNESS_RATIO,
)
from impactsph.models.columns import (
    VISCOSITY_FACTOR as CARRIED_FACTOR,
)
from impactsph.models.columns import (
    VISCOSITY_MEMORY as CARRIED_MEMORY,
)
from impactsph.physics.borrow import borrowed  # noqa: F401 (codegen's serial passes)
from impactsph.physics.chunked import SIMPLIFICATIONS_ONLY
from impactsph.physics.contact import (
    FRICTION_REGULARISATION,
    contact_acceleration_pair,
    contact_work_pair,
    friction_factor,
    in_contact,
)
from impactsph.physics.continuity import continuity_pair, velocity_gradient_pair
from impactsph.physics.momentum import viscous_acceleration_pair
from impactsph.physics.prefetch import prefetch_row
from impactsph.physics.reconstruction import reconstructed_approach
from impactsph.physics.records import record_columns, symmetric_index
from impactsph.physics.stress_rate import UPPER, jaumann_stress_rate_nd, store_upper
from impactsph.physics.survey import (
    SURVEY_CHUNK,
    SURVEY_START,
    rows_finite,
    store_survey,
    survey_chunks,
    survey_particle,
)

# >>> binding: replaced by impactsph.codegen in each generated copy
DIM = 3
GRADIENT_CORRECTION = False
FORCE_CORRECTION = False
ARTIFICIAL_STRESS = 0.0
ARTIFICIAL_STRESS_EXPONENT = 4.0
#: kappa = M_f / M of the initial lattice with the artificial stress's compensation, else 0
#: (subtracted from AS-3's weight ``f_ij^n`` in :func:`particle_rates`)
AS_COMPENSATION = 0.0
REFERENCE_Q = 1.0
PLANE_STRESS = False
VISCOSITY_FACTOR = False
VELOCITY_RECONSTRUCTION = False
AXISYMMETRIC = False
#: the records carry the work velocity, which the pair pass's energy terms read
#: (``time.energy_update = "compatible"``: :func:`particle_rates`)
COMPATIBLE_ENERGY = False
#: the module's one switch (``PassOptions.switch_kind``) has a neighbour loop written for
#: LLVM's vectoriser (``ViscosityScheme.switch_vectorises``): its pass gets SWITCH_FASTMATH
SWITCH_VECTORISED = False
#: every record has the same smoothing length (``PassOptions.uniform_h``): the pairs' ``h_ij``
#: is the particle's own (:func:`neighbour_separation`)
UNIFORM_H = False
#: the records are float32 (``PassOptions.record_precision``) and carry each position in two
#: parts, rounded (``X``) and the rest (``XL``), added in float64 (:func:`record_position`)
SPLIT_POSITIONS = False
#: the passes are compiled with numba's parallel transform (``PassOptions.parallel``; False:
#: plain loops over the same chunks, the same results, quicker to compile; codegen starts
#: each of them with ``a = borrowed(a)`` for its arguments: :mod:`impactsph.physics.borrow`)
PARALLEL = True
JIT = nb.njit
EOS_PARAMS = STRENGTH_PARAMS = DAMAGE_PARAMS = 6
STRENGTH_STATE = DAMAGE_STATE = 4
eos_pressure = strength_return = damage_update = pair_viscosity = viscosity_correction = None
viscosity_switch = None
# <<< binding

#: LLVM may use reciprocals in the pair pass; no reassociation, so sums keep their order.  Not
#: "contract" (fused multiply-adds): with it, passes compiled cold in a process and the same
#: passes served from numba's cache gave results differing at 1e-12 relative (the AC bars),
#: so a run's last digits depended on the cache's state; without it they agree bitwise
#: (``test_plugin_registers_the_models_for_the_command_line``, cold caches), at 6% of the step
#: time (benchmarks/README.md).  (The cause was numba's two compilations of a ``prange``
#: body, docs/architecture.md "One compiled code a pass"; these flags serve the passes that
#: keep their ``prange``.)
FASTMATH = {"arcp", "nsz"}
#: the pair pass also reassociates, so that LLVM can vectorise its first loop over the neighbours
#: (:func:`particle_rates`: the sums run as several partial sums, one per vector lane, added at
#: the end), and fuses multiply-adds ("contract", since 2026-12-05: the pair pass 0.91-0.94 of
#: its time without, benchmarks/README.md "Fused multiply-adds in the chunked passes").  The
#: order is fixed by the compiled code, so the results do not depend on the thread count or
#: on the cache's state: the passes with these flags have no ``prange`` loop, whose body numba
#: would compile twice (once as it runs in the process that compiled it, once as its cache
#: holds it, and reassociation or contraction lets the two differ), but run in shares of
#: their chunks (:mod:`impactsph.physics.chunked`; ``tests/test_parallel_passes.py`` holds a
#: compiling and a loading process to the serial passes' bits).
#: With ``error_model="numpy"`` (no zero-division checks, which are branches) this is what
#: lets the loop vectorise: 2.3x on the 2D pair loop alone (benchmarks/README.md).
PAIR_FASTMATH = {"reassoc", "arcp", "nsz", "contract"}
#: the chunked passes' pointer arguments are marked ``noalias``, as numba marks a ``prange``
#: body's (:func:`impactsph.jitcache.noalias_option`): they are called with distinct arrays
NOALIAS = noalias_option()
#: numba's ``parallel`` option of the passes: True, or for the serial passes its
#: simplifications (copy propagation, dead code) without the transform of ``prange`` loops
#: into threaded ones
PARALLEL_OPTION = True if PARALLEL else SIMPLIFICATIONS_ONLY
#: the chunked passes' (:mod:`impactsph.physics.chunked`) ``parallel`` option in every
#: module: the serial passes' simplifications, no transform (they have no ``prange``)
CHUNKED_OPTION = SIMPLIFICATIONS_ONLY
#: the error model of the passes that do not set their own: numba compiles a parallel loop's
#: body with "numpy" (no zero-division checks) whatever the function's, so the serial passes
#: (``PARALLEL = False``) take it too, for the same code in the loop
BODY_ERROR_MODEL = "python" if PARALLEL else "numpy"
#: the switch pass's flags: the pair pass's where the switch's neighbour loop is written for
#: the vectoriser (Balsara and Morris-Monaghan: their velocity-gradient loop,
#: :func:`impactsph.models.viscosity.switches.neighbour_fields`; the pass 40% faster on the
#: cantilever, benchmarks/README.md), none otherwise (Cullen-Dehnen's, with the same loop,
#: gained nothing; the AC switches' loops skip the pairs beyond their reach, like the
#: correction pass, and were 4% slower with them)
SWITCH_FASTMATH = PAIR_FASTMATH if SWITCH_VECTORISED else False
SWITCH_ERROR_MODEL = "numpy" if SWITCH_VECTORISED else "python"
#: the CPU's vectorised neighbour loops (pair, moment, velocity gradient, hourglass) run over
#: the neighbours within the support only, gathered first (:func:`support_range`), in 2D and
#: 3D: a quarter of a 3D list row is its Verlet skin, a sixth of a 2D row at the cases' h =
#: 1.3 dx, which the masked loops would evaluate in full (in 3D, with the gathering, the pair
#: pass took 0.77-0.84 of its time, the moment and hourglass passes 0.67-0.76, at 1e5
#: particles).  Since the rows are split at the support (``NeighbourList.splits``) only their
#: skin's entries are tested, which made it pay in 2D too: the 2D lattice's pair pass took
#: 0.91 of its time, the cantilever's step 0.90 (benchmarks/README.md, "The rows split at the
#: support").  Not in 1D (rows of four to six entries).
SKIN_FILTER = DIM > 1

_COLUMNS = record_columns(DIM, correction_matrix=FORCE_CORRECTION,
                          artificial_stress=ARTIFICIAL_STRESS > 0.0,
                          viscosity_factor=VISCOSITY_FACTOR, axisymmetric=AXISYMMETRIC,
                          velocity_gradient=VELOCITY_RECONSTRUCTION,
                          work_velocity=COMPATIBLE_ENERGY, split_positions=SPLIT_POSITIONS)
#: the columns of the hoop stress over the density and of the radius (AXISYMMETRIC only)
HOOP = _COLUMNS.get("hoop", 0)
RADIUS = _COLUMNS.get("radius", 0)
#: the density array is the mass per unit area of a layer of varying thickness (plane
#: stress: t / t0; axisymmetry: the radius r, the ring's length per radian), which the
#: thickness column of the common material state holds
THICK = PLANE_STRESS or AXISYMMETRIC
#: axisymmetry: the radius below which a particle's hoop terms take this many smoothing
#: lengths instead (a particle pushed onto the axis would otherwise divide by zero)
AXIS_FLOOR = 0.1
X, V, H, M, VOL, RHO, C, PC, BODY, A0, U = (_COLUMNS[k] for k in (
    "x", "v", "h", "m", "volume", "rho", "c", "pc", "body", "A", "u"))
#: first column of the positions' low parts (SPLIT_POSITIONS only)
XL = _COLUMNS.get("xl", 0)
#: the record's length padded to whole cache lines (rows of one particle each, a layout that
#: no backend uses now: the CPU's rows are unpadded, RECORD_COLUMNS, or U where no pass reads
#: the viscous acceleration (its columns are last); the GPU's records are columns,
#: ``RECORD_COLUMNS`` of them: :data:`impactsph.gpu.RECORD_ORDER`)
RECORD_WIDTH = _COLUMNS["width"]
RECORD_COLUMNS = _COLUMNS["columns"]
#: first column of the correction matrix C (FORCE_CORRECTION only; row by row)
CM0 = _COLUMNS.get("C", 0)
#: first column of the velocity gradient L (VELOCITY_RECONSTRUCTION only; row by row)
LV0 = _COLUMNS.get("Lv", 0)
#: first column of the work velocity (COMPATIBLE_ENERGY only)
W = _COLUMNS.get("w", 0)
#: columns of A's components: SYM[a][b] (a tuple of tuples: a compile-time constant)
SYM = tuple(tuple(A0 + symmetric_index(a, b, DIM) for b in range(DIM)) for a in range(DIM))
A00 = SYM[0][0]
A01, A11 = (SYM[0][1], SYM[1][1]) if DIM > 1 else (0, 0)
A02, A12, A22 = (SYM[0][2], SYM[1][2], SYM[2][2]) if DIM > 2 else (0, 0, 0)
#: columns of the artificial stress R's components (ARTIFICIAL_STRESS > 0 only), as A's
RS0 = _COLUMNS.get("R", 0)
R00 = RS0
R01, R11 = (RS0 + symmetric_index(0, 1, DIM), RS0 + symmetric_index(1, 1, DIM)) \
    if DIM > 1 else (0, 0)
R02, R12, R22 = (RS0 + symmetric_index(0, 2, DIM), RS0 + symmetric_index(1, 2, DIM),
                 RS0 + symmetric_index(2, 2, DIM)) if DIM > 2 else (0, 0, 0)
#: ``1 / W(dx)`` in units of the kernel's shape (:func:`artificial_stress_weight`)
AS_REFERENCE = 1.0 / getattr(cubic_spline_shape, "py_func", cubic_spline_shape)(REFERENCE_Q)
#: cyclic Jacobi sweeps of the 3D principal-stress decomposition (:func:`tension_part_3d`):
#: the off-diagonal part falls quadratically; measured on 3000 random symmetric matrices
#: (entries over eight decades), the tensile part is off by 8e-2, 1e-5 and 3e-15 of the
#: largest entry after 2, 3 and 4 sweeps; six leave a margin
JACOBI_SWEEPS = 6
#: the kernel gradient correction is whole above ``det B = MOMENT_FULL`` and off below
#: ``MOMENT_NONE``, blended in between (:func:`moment_inverse`): the geometric mean of B's
#: eigenvalues, ``det B^(1/DIM)``, at 0.15 and 0.05.  B is the identity for a complete
#: support; at h = 1.3 dx that mean is 0.51 at the end of a 1D lattice, 0.37 and 0.27 at a
#: 2D and 3D lattice corner, 0.30 and 0.19 at a corner jittered by 0.2 dx; a particle thrown
#: out of the body with a neighbour or two has far less.
MOMENT_FULL = 0.15 ** DIM
MOMENT_NONE = 0.05 ** DIM
#: the record columns a correction reads: (x, v, h, volume, body, u)
CORRECTION_COLUMNS = (X, V, H, VOL, BODY, U)
#: the viscosity factor's column (VISCOSITY_FACTOR only)
VF = _COLUMNS.get("f", 0)
#: the record columns a viscosity switch reads: (x, v, h, volume, body, u, c, f, memory, rho,
#: m)
SWITCH_COLUMNS = (X, V, H, VOL, BODY, U, C, VF, VF + 1, RHO, M)


@JIT(inline="always", cache=True)
def material_pressure(table, k, rho, e):
    """Pressure of material ``k`` (a row of the material table) at ``rho``, ``e``."""
    row = table[k]
    return eos_pressure(int(row[EOS_KIND]), rho, e, row[RHO0], row[BULK], row[EOS_PARAMS:])


@JIT(inline="always", cache=True)
def tension_part_2d(a00, a01, a11):
    """The tensile part of the symmetric 2x2 tensor ``a`` (Pa, or Pa/(kg/m^3)^2 for
    ``A = sigma/rho^2``): its positive eigenvalues on their eigenvectors,
    ``sum_k max(lambda_k, 0) e_k (x) e_k``, as ``(t00, t01, t11)``.

    Gray, Monaghan & Swift (2001) eqs 2.9-2.11: the principal axes are at the angle theta
    with ``tan 2 theta = 2 a01 / (a00 - a11)``, the principal components are
    ``a'_xx, a'_yy = (a00 + a11)/2 +- sqrt(((a00 - a11)/2)^2 + a01^2)``, and the tensor goes
    back by ``t00 = t'_xx cos^2 theta + t'_yy sin^2 theta``, ``t11 = t'_xx sin^2 theta +
    t'_yy cos^2 theta``, ``t01 = (t'_xx - t'_yy) sin theta cos theta``.  Written with the
    double angle (``cos^2 theta = (1 + cos 2 theta)/2``, ...) it needs no trigonometric
    function; ``theta = 0`` for an isotropic tensor."""
    half = 0.5 * (a00 - a11)
    radius = math.sqrt(half * half + a01 * a01)
    mean = 0.5 * (a00 + a11)
    if radius > 0.0:
        c2 = half / radius  # cos 2 theta
        s2 = a01 / radius  # sin 2 theta
    else:
        c2 = 1.0
        s2 = 0.0
    t1 = max(mean + radius, 0.0)  # along (cos theta, sin theta)
    t2 = max(mean - radius, 0.0)  # along (-sin theta, cos theta)
    cc = 0.5 * (1.0 + c2)
    ss = 0.5 * (1.0 - c2)
    return t1 * cc + t2 * ss, 0.5 * (t1 - t2) * s2, t1 * ss + t2 * cc


@JIT(inline="always", cache=True)
def jacobi_rotation(app, aqq, apq):
    """``(t, c, s)`` of the plane rotation that zeroes ``a_pq`` of a symmetric matrix
    (Jacobi's method, as in Press et al., Numerical Recipes, section 11.1): with
    ``theta = (a_qq - a_pp) / (2 a_pq)``, ``t = sgn(theta) / (|theta| + sqrt(theta^2 + 1))``
    (the smaller angle), ``c = 1 / sqrt(t^2 + 1)``, ``s = t c``; the identity for
    ``a_pq = 0``."""
    if apq == 0.0:
        return 0.0, 1.0, 0.0
    theta = (aqq - app) / (2.0 * apq)
    if abs(theta) > 1e150:  # theta^2 would overflow: t = 1 / (2 theta) to round-off
        t = 0.5 / theta
    else:
        t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / math.sqrt(t * t + 1.0)
    return t, c, t * c


@JIT(inline="always", cache=True)
def tension_part_3d(a00, a01, a02, a11, a12, a22):
    """The tensile part ``sum_k max(lambda_k, 0) e_k (x) e_k`` of the symmetric 3x3 tensor
    ``a``, as its upper triangle ``(t00, t01, t02, t11, t12, t22)``.  The eigen-decomposition
    is ``JACOBI_SWEEPS`` cyclic Jacobi sweeps over the pairs (0, 1), (0, 2), (1, 2)
    (:func:`jacobi_rotation`; ``a' = J^T a J``, the eigenvectors the columns of the product
    ``V`` of the rotations), all in scalars, so that it compiles for the CUDA kernels too."""
    v00 = v11 = v22 = 1.0
    v01 = v02 = v10 = v12 = v20 = v21 = 0.0
    for _ in range(JACOBI_SWEEPS):
        # (p, q) = (0, 1), r = 2
        t, c, s = jacobi_rotation(a00, a11, a01)
        a00 -= t * a01
        a11 += t * a01
        a01 = 0.0
        a02, a12 = c * a02 - s * a12, c * a12 + s * a02
        v00, v01 = c * v00 - s * v01, s * v00 + c * v01
        v10, v11 = c * v10 - s * v11, s * v10 + c * v11
        v20, v21 = c * v20 - s * v21, s * v20 + c * v21
        # (p, q) = (0, 2), r = 1
        t, c, s = jacobi_rotation(a00, a22, a02)
        a00 -= t * a02
        a22 += t * a02
        a02 = 0.0
        a01, a12 = c * a01 - s * a12, c * a12 + s * a01
        v00, v02 = c * v00 - s * v02, s * v00 + c * v02
        v10, v12 = c * v10 - s * v12, s * v10 + c * v12
        v20, v22 = c * v20 - s * v22, s * v20 + c * v22
        # (p, q) = (1, 2), r = 0
        t, c, s = jacobi_rotation(a11, a22, a12)
        a11 -= t * a12
        a22 += t * a12
        a12 = 0.0
        a01, a02 = c * a01 - s * a02, c * a02 + s * a01
        v01, v02 = c * v01 - s * v02, s * v01 + c * v02
        v11, v12 = c * v11 - s * v12, s * v11 + c * v12
        v21, v22 = c * v21 - s * v22, s * v21 + c * v22
    p0 = max(a00, 0.0)
    p1 = max(a11, 0.0)
    p2 = max(a22, 0.0)
    return (p0 * v00 * v00 + p1 * v01 * v01 + p2 * v02 * v02,
            p0 * v00 * v10 + p1 * v01 * v11 + p2 * v02 * v12,
            p0 * v00 * v20 + p1 * v01 * v21 + p2 * v02 * v22,
            p0 * v10 * v10 + p1 * v11 * v11 + p2 * v12 * v12,
            p0 * v10 * v20 + p1 * v11 * v21 + p2 * v12 * v22,
            p0 * v20 * v20 + p1 * v21 * v21 + p2 * v22 * v22)


@JIT(inline="always", cache=True)
def artificial_stress_record(P, p):
    """The artificial stress ``R_i`` of the record in row ``p`` into its ``R`` columns
    (ARTIFICIAL_STRESS > 0 only; Monaghan 2000, Gray, Monaghan & Swift 2001, section 2):

        (AS-1)  R'_aa = -epsilon sigma'_aa / rho_i^2  if sigma'_aa > 0 (tension), else 0

    in the principal axes of the stress ``sigma_i = -P_i I + S_i`` (Pa), rotated back to the
    axes of the problem; ``R`` (m^5/(kg s^2), like ``A = sigma/rho^2``) is ``-epsilon`` times
    the tensile part of ``A_i`` (:func:`tension_part_2d`, :func:`tension_part_3d`).  In 1D
    ``R = -epsilon max(sigma_xx, 0) / rho^2``; in 2D (plane strain) the in-plane 2x2 part of
    the stress, the only one the in-plane forces see."""
    eps = ARTIFICIAL_STRESS
    if DIM == 1:
        P[p, R00] = -eps * max(P[p, A00], 0.0)
    elif DIM == 2:
        t00, t01, t11 = tension_part_2d(P[p, A00], P[p, A01], P[p, A11])
        P[p, R00] = -eps * t00
        P[p, R01] = -eps * t01
        P[p, R11] = -eps * t11
    else:
        t00, t01, t02, t11, t12, t22 = tension_part_3d(P[p, A00], P[p, A01], P[p, A02],
                                                       P[p, A11], P[p, A12], P[p, A22])
        P[p, R00] = -eps * t00
        P[p, R01] = -eps * t01
        P[p, R02] = -eps * t02
        P[p, R11] = -eps * t11
        P[p, R12] = -eps * t12
        P[p, R22] = -eps * t22


@JIT(inline="always", cache=True)
def artificial_stress_weight(q):
    """``f_ij^n`` (Monaghan 2000; Gray et al. 2001 section 2):

        (AS-2)  f_ij = W(r_ij, h_ij) / W(dx, h_ij)

    at ``q = r_ij / h_ij``; the reference distance is the initial spacing,
    ``dx / h = REFERENCE_Q`` (``1 / kernel.h_over_dx``), so ``f = 1`` at a nearest neighbour
    of the lattice and falls to 0 at ``2 h``.  The kernel's constant cancels: only its shape
    (:func:`impactsph.kernels.cubic_spline_shape`) is needed.  The exponent
    ``n = ARTIFICIAL_STRESS_EXPONENT`` (4: two products)."""
    f = cubic_spline_shape(q) * AS_REFERENCE
    if ARTIFICIAL_STRESS_EXPONENT == 4.0:
        f2 = f * f
        return f2 * f2
    return f ** ARTIFICIAL_STRESS_EXPONENT


@JIT(inline="always", cache=True)
def particle_record(p, i, x, v, m, rho, e, S, carried, h, body, material, table, P):
    """Pass 1 for particle ``i`` at sorted position ``p``: ``P``, ``c = sqrt(M/rho)``, and its
    packed record (``V = m/rho``, ``P/rho^2``, ``A = (-P I + S)/rho^2``, ...) in row ``p``;
    with the artificial stress, ``R`` (:func:`artificial_stress_record`).  ``carried`` holds
    the common material state's columns (:mod:`impactsph.models.columns`).

    The damage ``D = carried[i, DAMAGE]`` acts here (Benz & Asphaug 1995, section 3.2): the
    forces see ``(1 - D) S`` and, in tension, ``(1 - D) P``; the stored stress stays undamaged
    (the strength model's return and the damage models read it).

    In plane stress ``rho`` is the mass per unit area over the initial thickness ``t0`` and
    the material's density is ``rho / tau`` with ``tau = t / t0``: the EOS and the wave speed
    take that, and the forces the stress resultant per unit initial thickness ``tau sigma``
    (``rho dv/dt = div(tau sigma)``, the thickness varying from particle to particle).  In
    axisymmetry ``rho`` is the mass per radian and unit area of the r-z plane, ``rho_m r``
    (``tau = r``), the stress columns hold ``|r| sigma / rho`` and ``P |r| / rho`` (``r = x``;
    a mirror ghost across the axis has ``x < 0``), and the record also holds
    ``sigma_tt / rho`` and ``r`` (floored, > 0) for the hoop terms (:func:`particle_rates`)."""
    k = material[i]
    tau = carried[i, THICKNESS_RATIO] if THICK else 1.0
    rho_m = rho[i] / tau if THICK else rho[i]
    pr = material_pressure(table, k, rho_m, e[i])
    intact = 1.0 - carried[i, DAMAGE]
    if pr < 0.0:
        pr *= intact
    c = math.sqrt(table[k, WAVE_MODULUS] / rho_m)
    if AXISYMMETRIC:  # A = r sigma / rho, r = |x| (docs/modelling.md)
        inv_rho2 = abs(x[i, 0]) / rho[i]
    else:  # A = tau sigma / rho^2 (tau = 1 but in plane stress)
        inv_rho2 = tau / (rho[i] * rho[i])
    for a in range(DIM):
        P[p, X + a] = x[i, a]
        if SPLIT_POSITIONS:  # the rest of the position, after the record's rounding
            P[p, XL + a] = x[i, a] - np.float64(P[p, X + a])
        P[p, V + a] = v[i, a]
        if COMPATIBLE_ENERGY:  # the work velocity: the velocity, but in the work pass
            P[p, W + a] = v[i, a]
        for b in range(a, DIM):
            P[p, SYM[a][b]] = intact * S[i, a, b] * inv_rho2
        P[p, SYM[a][a]] -= pr * inv_rho2
    P[p, H] = h[i]
    P[p, M] = m[i]
    P[p, VOL] = m[i] / rho[i]
    P[p, RHO] = rho[i]
    P[p, C] = c
    P[p, PC] = pr * inv_rho2
    P[p, BODY] = body[i]
    if AXISYMMETRIC:  # the hoop stress sigma_tt (the carried one) over rho = rho_m r
        P[p, HOOP] = (intact * S[i, 2, 2] - pr) / rho[i]
        P[p, RADIUS] = tau
    if ARTIFICIAL_STRESS > 0.0:
        artificial_stress_record(P, p)
    if VISCOSITY_FACTOR:
        P[p, VF] = carried[i, CARRIED_FACTOR]
        P[p, VF + 1] = carried[i, CARRIED_MEMORY]


@JIT(inline="always", cache=True)
def moment_inverse(B00, B01, B02, B10, B11, B12, B20, B21, B22):
    """``(corrected, M)``: the matrix that corrects with the moment matrix ``B`` (its
    ``DIM x DIM`` part), row by row: ``B^-1`` where ``det B >= MOMENT_FULL``, the identity
    where ``det B <= MOMENT_NONE`` (``corrected`` False), and in between the blend
    ``w B^-1 + (1 - w) I`` with the smooth step ``w = 3 t^2 - 2 t^3`` of
    ``t = (det B - MOMENT_NONE) / (MOMENT_FULL - MOMENT_NONE)``.  A nearly singular ``B``
    (a particle thrown out of the body with a neighbour or two) would make the correction,
    and the forces, arbitrarily large; the blend also keeps the correction continuous as a
    particle's neighbourhood thins, which the time integration needs."""
    if DIM == 1:
        det = B00
    elif DIM == 2:
        det = B00 * B11 - B01 * B10
    else:
        det = (B00 * (B11 * B22 - B12 * B21) - B01 * (B10 * B22 - B12 * B20)
               + B02 * (B10 * B21 - B11 * B20))
    if det <= MOMENT_NONE:
        return False, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    inv = 1.0 / det
    if DIM == 1:
        M = (inv, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    elif DIM == 2:
        M = (B11 * inv, -B01 * inv, 0.0, -B10 * inv, B00 * inv, 0.0, 0.0, 0.0, 0.0)
    else:
        M = ((B11 * B22 - B12 * B21) * inv, (B02 * B21 - B01 * B22) * inv,
             (B01 * B12 - B02 * B11) * inv, (B12 * B20 - B10 * B22) * inv,
             (B00 * B22 - B02 * B20) * inv, (B02 * B10 - B00 * B12) * inv,
             (B10 * B21 - B11 * B20) * inv, (B01 * B20 - B00 * B21) * inv,
             (B00 * B11 - B01 * B10) * inv)
    if det >= MOMENT_FULL:
        return (True, M[0], M[1], M[2], M[3], M[4], M[5], M[6], M[7], M[8])
    t = (det - MOMENT_NONE) / (MOMENT_FULL - MOMENT_NONE)
    w = t * t * (3.0 - 2.0 * t)
    u = 1.0 - w
    return (True, w * M[0] + u, w * M[1], w * M[2], w * M[3], w * M[4] + u, w * M[5],
            w * M[6], w * M[7], w * M[8] + u)


@JIT(inline="always", cache=True)
def correct_velocity_gradient(L, B00, B01, B02, B10, B11, B12, B20, B21, B22):
    """Kernel gradient correction of the velocity gradient (Randles & Libersky 1996; Bonet &
    Lok 1999): with the moment matrix ``B = -sum_j V_j r_ij (x) grad W_ij`` (the identity for
    a complete kernel support, not at a free surface), the SPH gradient of a linear field
    ``v = A x`` is ``L = A B``, so ``L <- L B^-1`` recovers ``A`` exactly wherever ``B`` is
    invertible.  Where ``det B`` is small (a particle with too few neighbours to span the
    space) the correction is blended out (:func:`moment_inverse`)."""
    ok, I00, I01, I02, I10, I11, I12, I20, I21, I22 = moment_inverse(
        B00, B01, B02, B10, B11, B12, B20, B21, B22)
    if not ok:
        return
    Bi = ((I00, I01, I02), (I10, I11, I12), (I20, I21, I22))
    for a in range(DIM):
        row = (L[a, 0], L[a, 1] if DIM > 1 else 0.0, L[a, 2] if DIM > 2 else 0.0)
        for b in range(DIM):
            s = 0.0
            for c in range(DIM):
                s += row[c] * Bi[c][b]
            L[a, b] = s


@JIT(inline="always", cache=True)
def apply_correction(record, b, w0, w1, w2):
    """Component ``b`` of ``C w`` for the correction matrix ``C`` in a packed record (row by
    row from column ``CM0``): a row vector ``w`` times ``C^T`` gives the same."""
    if b >= DIM:
        return 0.0
    s = record[CM0 + b * DIM] * w0
    if DIM > 1:
        s += record[CM0 + b * DIM + 1] * w1
    if DIM > 2:
        s += record[CM0 + b * DIM + 2] * w2
    return s


@JIT(inline="always", cache=True)
def corrected(record, w0, w1, w2):
    """``C w`` (a column vector), or a row vector ``w`` times ``C^T``: the three components
    of :func:`apply_correction`."""
    return (apply_correction(record, 0, w0, w1, w2), apply_correction(record, 1, w0, w1, w2),
            apply_correction(record, 2, w0, w1, w2))


@JIT(inline="always", cache=True)
def record_position(R, a):
    """Component ``a`` of the position a packed record ``R`` (a row) holds: ``R[X + a]``, or
    with ``SPLIT_POSITIONS`` its two parts added in float64, ``R[X + a] + R[XL + a]``, which
    is the position to about 48 bits (the pair separations of float32 records then lose
    nothing to the bodies' distance from the origin)."""
    if SPLIT_POSITIONS:
        return np.float64(R[X + a]) + R[XL + a]
    return R[X + a]


@JIT(inline="always", cache=True)
def neighbour_position(P, j, a):
    """:func:`record_position` of row ``j`` of the records ``P``, read as ``P[j, col]`` (the
    vectorised neighbour loops' reads: a row view stops the vectoriser)."""
    if SPLIT_POSITIONS:
        return np.float64(P[j, X + a]) + P[j, XL + a]
    return P[j, X + a]


@JIT(inline="always", cache=True)
def pair_separation(Pi_, Pj):
    """``(d0, d1, d2, r2, h_ij, inv_h, q2)`` of a pair of packed records: ``r_ij = x_i - x_j``
    (its components beyond DIM zero), ``|r_ij|^2``, the mean smoothing length, its inverse
    and ``(r_ij / h_ij)^2`` (the pair is within the kernel's support while ``q2 < 4``)."""
    d0 = record_position(Pi_, 0) - record_position(Pj, 0)
    d1 = record_position(Pi_, 1) - record_position(Pj, 1) if DIM > 1 else 0.0
    d2 = record_position(Pi_, 2) - record_position(Pj, 2) if DIM > 2 else 0.0
    r2 = d0 * d0 + d1 * d1 + d2 * d2
    h_ij = 0.5 * (Pi_[H] + Pj[H])
    inv_h = 1.0 / h_ij
    return d0, d1, d2, r2, h_ij, inv_h, r2 * inv_h * inv_h


@JIT(inline="always", cache=True)
def neighbour_separation(xi0, xi1, xi2, hi, P, j):
    """:func:`pair_separation` for the vectorised neighbour loops: particle ``i``'s position
    and smoothing length already read, the neighbour's record read as ``P[j, col]`` (a row
    view ``P[j]`` stops the vectoriser).  With ``UNIFORM_H`` (every record's h the same)
    ``h_ij`` is ``h_i``, which ``(h_i + h_j) / 2`` then is to the bit: the neighbour's h is
    not read and ``1 / h_ij``, the same for every neighbour, is left to LLVM to hoist out of
    the loop (issue 16: one gather and one division a pair)."""
    d0 = xi0 - neighbour_position(P, j, 0)
    r2 = d0 * d0
    d1 = d2 = 0.0
    if DIM > 1:
        d1 = xi1 - neighbour_position(P, j, 1)
        r2 += d1 * d1
    if DIM > 2:
        d2 = xi2 - neighbour_position(P, j, 2)
        r2 += d2 * d2
    h_ij = hi if UNIFORM_H else 0.5 * (hi + P[j, H])
    inv_h = 1.0 / h_ij
    return d0, d1, d2, r2, h_ij, inv_h, r2 * inv_h * inv_h


@JIT(inline="always", cache=True)
def support_range(xi0, xi1, xi2, hi, P, offsets, indices, p, listed, starts, filter_skin):
    """The neighbours of sorted position ``p`` for a vectorised pair loop, as the range
    ``(first, last)`` of ``listed`` to run over: ``for k in range(first, last): j =
    listed[k]``.

    With ``filter_skin`` (the CPU passes in 2D and 3D, :data:`SKIN_FILTER`; ``listed`` is then a
    scratch, :func:`chunk_listed`) the row's front part, ``indices[offsets[p]:starts[p]]``
    (``NeighbourList.filter_starts``: the pairs within their support when the list was
    built), copied as it is, then those of the rest of the row within the kernel support now
    (``q < 2``, the loops' own test, by :func:`neighbour_separation`), in the list's order;
    otherwise (1D, and the GPU's kernels, which have no such scratch;
    ``listed`` is then ``indices``) the list's whole row.  The list also holds the pairs of
    its Verlet skin, a quarter of a 3D row at a skin of 0.1 of the support, which a
    vectorised loop would evaluate in full and mask; the test is a few operations a pair
    against some 60 in the pair loop, and the front part needs none (the test of every entry
    was a quarter of the 3D pass's time before the rows were split; issue 16,
    benchmarks/README.md).  A front pair that has
    left the support since the build is masked by the loop, as every pair is, and a skin
    pair that has entered it is found by the test, so the pairs summed are the same whatever
    the split.  The test is branch-free: each entry is written, and the count moves past it
    only if it is inside.  The pairs left out contribute nothing to any sum (their kernel
    gradient is zero), so only the grouping of the sums' partial sums changes
    (round-off)."""
    if SKIN_FILTER:  # a constant: in 1D numba prunes the branch
        if filter_skin:
            start = offsets[p]
            end = offsets[p + 1]
            # (held inside the row: any split gives the same pairs, the loop masks the front
            # part's pairs that have left the support, so a list whose splits are not its own
            # costs time, never memory or correctness)
            split = min(max(starts[p], start), end)
            count = split - start
            for k in range(count):  # the front part, within the support at the build
                listed[k] = indices[start + k]
            for k in range(split, end):
                j = indices[k]
                q2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)[6]
                listed[count] = j
                count += 1 if q2 < 4.0 else 0
            return 0, count
    return offsets[p], offsets[p + 1]


@JIT(inline="always", cache=True)
def chunk_listed(offsets, indices, start, stop):
    """What the vectorised loops of the sorted positions ``start`` to ``stop - 1`` (one
    chunk of a parallel pass) read their neighbours from, :func:`support_range`'s
    ``listed``: in 2D and 3D (:data:`SKIN_FILTER`) a scratch as long as the chunk's longest
    list row, in 1D the list itself."""
    if SKIN_FILTER:  # a constant: in 1D numba prunes the branch
        longest = 0
        for p in range(start, stop):
            longest = max(longest, offsets[p + 1] - offsets[p])
        return np.empty(longest, dtype=indices.dtype)
    return indices


@JIT(inline="always", cache=True)
def moment_correction(p, P, offsets, indices, listed, starts, filter_skin):
    """The correction matrix of the particle at sorted position ``p`` into its record:
    ``C = B^-T`` with the moment matrix ``B = -sum_j V_j r_ij (x) grad W_ij`` over the
    neighbours of the same body (see :func:`correct_velocity_gradient`), so that ``C grad
    W_ij`` is the corrected kernel gradient; blended to the identity where ``det B`` is small
    (:func:`moment_inverse`)."""
    Pi_ = P[p]
    bi = Pi_[BODY]
    xi0 = record_position(Pi_, 0)
    xi1 = record_position(Pi_, 1) if DIM > 1 else 0.0
    xi2 = record_position(Pi_, 2) if DIM > 2 else 0.0
    hi = Pi_[H]
    B00 = B01 = B02 = B11 = B12 = B22 = 0.0  # (B is symmetric)
    # one loop without branches, vectorised as particle_rates' first loop (the support and
    # the body as a mask on the weight; moment_pass's flags)
    first, last = support_range(xi0, xi1, xi2, hi, P, offsets, indices, p, listed, starts,
                                filter_skin)
    for k in range(first, last):
        j = listed[k]
        d0, d1, d2, r2, _, inv_h, q2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)
        inside = (q2 < 4.0) & (r2 > 0.0) & (P[j, BODY] == bi)
        fq = cubic_spline_gradient_factor(math.sqrt(q2), inv_h, DIM) if inside else 0.0
        w = -P[j, VOL] * fq
        B00 += w * d0 * d0
        if DIM > 1:
            B01 += w * d0 * d1
            B11 += w * d1 * d1
        if DIM > 2:
            B02 += w * d0 * d2
            B12 += w * d1 * d2
            B22 += w * d2 * d2
    # B is symmetric (r_ij (x) r_ij times a number): its lower triangle is its upper
    B10, B20, B21 = B01, B02, B12
    _, I00, I01, I02, I10, I11, I12, I20, I21, I22 = moment_inverse(
        B00, B01, B02, B10, B11, B12, B20, B21, B22)
    Bi = ((I00, I01, I02), (I10, I11, I12), (I20, I21, I22))
    for a in range(DIM):  # C = B^-T, row by row
        for b in range(DIM):
            P[p, CM0 + a * DIM + b] = Bi[b][a]


@JIT(inline="always", cache=True)
def velocity_gradient_record(p, P, offsets, indices, listed, starts, filter_skin):
    """The symmetric part ``(L + L^T) / 2`` of the velocity gradient of the row at sorted
    position ``p`` into its record (VELOCITY_RECONSTRUCTION only; the slopes ``r . L r`` of
    :mod:`impactsph.physics.reconstruction` see only that part), with the kernel gradient
    correction so that a linear field's is exact where the support spans the space::

        L_i = (-sum_j V_j v_ij (x) grad W_ij) B_i^-1,   B_i = -sum_j V_j r_ij (x) grad W_ij

    over the neighbours of the same body (:func:`correct_velocity_gradient`; blended to the
    uncorrected sum where ``det B`` is small, :func:`moment_inverse`).  One loop without
    branches, vectorised as :func:`moment_correction`'s.  Stored as the whole ``DIM x DIM``
    matrix, row by row, so that a symmetry plane's ghost gets its mirror ``R L R`` as a
    correction matrix does."""
    Pi_ = P[p]
    bi = Pi_[BODY]
    xi0 = record_position(Pi_, 0)
    xi1 = record_position(Pi_, 1) if DIM > 1 else 0.0
    xi2 = record_position(Pi_, 2) if DIM > 2 else 0.0
    vi0 = Pi_[V]
    vi1 = Pi_[V + 1] if DIM > 1 else 0.0
    vi2 = Pi_[V + 2] if DIM > 2 else 0.0
    hi = Pi_[H]
    B00 = B01 = B02 = B11 = B12 = B22 = 0.0  # (B is symmetric)
    L00 = L01 = L02 = L10 = L11 = L12 = L20 = L21 = L22 = 0.0
    first, last = support_range(xi0, xi1, xi2, hi, P, offsets, indices, p, listed, starts,
                                filter_skin)
    for k in range(first, last):
        j = listed[k]
        d0, d1, d2, r2, _, inv_h, q2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)
        inside = (q2 < 4.0) & (r2 > 0.0) & (P[j, BODY] == bi)
        fq = cubic_spline_gradient_factor(math.sqrt(q2), inv_h, DIM) if inside else 0.0
        w = -P[j, VOL] * fq  # -V_j times grad W_ij / r_ij
        u0 = vi0 - P[j, V]
        B00 += w * d0 * d0
        L00 += w * u0 * d0
        if DIM > 1:
            u1 = vi1 - P[j, V + 1]
            B01 += w * d0 * d1
            B11 += w * d1 * d1
            L01 += w * u0 * d1
            L10 += w * u1 * d0
            L11 += w * u1 * d1
        if DIM > 2:
            u2 = vi2 - P[j, V + 2]
            B02 += w * d0 * d2
            B12 += w * d1 * d2
            B22 += w * d2 * d2
            L02 += w * u0 * d2
            L12 += w * u1 * d2
            L20 += w * u2 * d0
            L21 += w * u2 * d1
            L22 += w * u2 * d2
    # B is symmetric (r_ij (x) r_ij times a number): its lower triangle is its upper
    B10, B20, B21 = B01, B02, B12
    _, I00, I01, I02, I10, I11, I12, I20, I21, I22 = moment_inverse(
        B00, B01, B02, B10, B11, B12, B20, B21, B22)
    Bi = ((I00, I01, I02), (I10, I11, I12), (I20, I21, I22))
    Lt = ((L00, L01, L02), (L10, L11, L12), (L20, L21, L22))
    for a in range(DIM):  # the symmetric part of L B^-1, row by row
        for b in range(DIM):
            s = 0.0
            for c in range(DIM):
                s += Lt[a][c] * Bi[c][b] + Lt[b][c] * Bi[c][a]
            P[p, LV0 + a * DIM + b] = 0.5 * s


@JIT(inline="always", cache=True)
def projected_slope(P, row, col0, d0, d1, d2):
    """``r . L r`` (m^2/s) for ``r = (d0, d1, d2)`` and a symmetric ``L`` stored row by row
    from column ``col0`` of the record at sorted position ``row``: its diagonal and upper
    triangle only, ``sum_a L_aa d_a^2 + 2 sum_{a<b} L_ab d_a d_b`` (3 and 6 loads in 2D and
    3D instead of 4 and 9)."""
    s = P[row, col0] * d0 * d0
    if DIM > 1:
        s += P[row, col0 + DIM + 1] * d1 * d1 + 2.0 * P[row, col0 + 1] * d0 * d1
    if DIM > 2:
        s += (P[row, col0 + 2 * DIM + 2] * d2 * d2
              + 2.0 * (P[row, col0 + 2] * d0 * d2 + P[row, col0 + DIM + 2] * d1 * d2))
    return s


@JIT(inline="always", cache=True)
def stress_along(record, d0, d1, d2):
    """``d . A . d`` for the symmetric ``A = sigma/rho^2`` of a packed record."""
    s = record[A00] * d0 * d0
    if DIM > 1:
        s += record[A11] * d1 * d1 + 2.0 * record[A01] * d0 * d1
    if DIM > 2:
        s += record[A22] * d2 * d2 + 2.0 * (record[A02] * d0 * d2 + record[A12] * d1 * d2)
    return s


@JIT(inline="always", cache=True)
def contact_traction(Pi_, Pj, d0, d1, d2, r2, normal_stress):
    """``(s_i, s_j)``: each particle's share of the contact push of a pair of different bodies
    (over rho^2): the compressive normal stress along ``r_ij`` with ``normal_stress``, else
    the pressure (``P/rho^2``; docs/modelling.md, "Contact between bodies")."""
    if normal_stress:
        return -stress_along(Pi_, d0, d1, d2) / r2, -stress_along(Pj, d0, d1, d2) / r2
    return Pi_[PC], Pj[PC]


@JIT(cache=True, fastmath=FASTMATH)
def stress_rate(L, S_i, shear, dS_i):
    """:func:`impactsph.physics.stress_rate.jaumann_stress_rate` as a call of its own, not
    inlined into the pair pass.  It was made one when the pair pass was a ``prange`` loop: with
    the pass's reassociating flags (PAIR_FASTMATH) on it, a compiling and a loading process
    gave stress rates that differed in the last bit (:mod:`impactsph.physics.chunked`).  That
    cause is gone, but inlined it measured no better (2026-12-06, ``bench_pass_ab.py``: 0.975
    of the pass's time in 2D, 1.02 in 3D, medians; benchmarks/README.md), so it stays a call.
    ``DIM`` is passed as a constant, so the loops unroll
    (:func:`impactsph.physics.stress_rate.jaumann_stress_rate_nd`)."""
    jaumann_stress_rate_nd(L, S_i, shear, dS_i, DIM)


@JIT(inline="always", cache=True)
def particle_rates(p, i, P, offsets, indices, visc_kind, visc_params, normal_stress, S, material,
                   table, drho, dv, de, de_visc, contact_force, pair_count, dS, L, L_sorted,
                   listed, starts, filter_skin):
    """Pass 2 for the active particle ``i`` at sorted position ``p``: the sums over its
    neighbours (eqs 22, 27, 28) and its stress rate (eq 14, its six components into
    ``dS[i]``, with ``L`` as scratch for the velocity gradient); its viscous acceleration
    is also stored in its packed record, for a correction pass.
    ``contact_force`` is written only if it has a row per particle (several bodies or walls),
    ``L_sorted[p]`` (the velocity gradient, for the hourglass control) only if it has rows.
    The first loop runs over :func:`support_range`'s neighbours (``listed``, ``filter_skin``).

    The stress terms are regrouped, exactly in arithmetic: ``sum_j m_j A_i . grad W_ij =
    A_i . (sum_j m_j grad W_ij)`` and ``sum_j m_j A_i : (v_ij (x) grad W_ij) = A_i : (sum_j
    m_j v_ij (x) grad W_ij)``, so ``A_i`` is applied once per particle.  Other sums share
    their products (issue 16; benchmarks/README.md, "Fewer operations a pair"): the
    continuity sum ``sum_j V_j v_ij . grad W_ij`` is minus the trace of the velocity
    gradient's sum; the viscous terms are multiples of ``fq r_ij`` (``grad W_ij = fq r_ij``),
    so the viscous heating is ``-1/2`` the viscous acceleration's coefficient times ``z_ij .
    r_ij``; the weighted gradients ``m_j grad W_ij`` serve the stress, ``G`` and ``T`` sums
    alike; and the viscous push across bodies (a part of the contact force, for the few
    particles at a contact) is summed in a loop of its own over those particles' rows, not
    masked in the first (nor in the contact loop, where it cost the 3D CUDA kernel a block of
    threads a multiprocessor: the comment at that loop).  The results move at round-off
    (``tests/test_rates_reference.py`` checks the whole against the term functions summed
    pair by pair).

    With the artificial stress (``ARTIFICIAL_STRESS`` = epsilon > 0; Monaghan 2000, Gray,
    Monaghan & Swift 2001, section 2) each pair of the same body also adds

        (AS-3)  dv_i/dt += m_j f_ij^n (R_i + R_j) . grad W_ij                     (m/s^2)
        (AS-4)  de_i/dt -= 1/2 m_j f_ij^n v_ij . (R_i + R_j) . grad W_ij          (W/kg)

    with ``R`` of :func:`artificial_stress_record` (eq AS-1, negative in tension, so the pair
    repels) and ``f_ij^n`` of :func:`artificial_stress_weight` (eq AS-2): the same form as the
    stress term ``m_j (A_i + A_j) . grad W_ij``.  With the compensation (``AS_COMPENSATION`` =
    kappa > 0, ``stabilisation.artificial_stress_compensation``) the weight is ``f_ij^n -
    kappa``: for a long wave on the lattice AS-3 gives ``M_f rho grad R`` and the ``-kappa``
    part ``-kappa M rho grad R`` (both on the uncorrected ``grad W_ij``), so with ``kappa = M_f
    / M`` the smooth parts cancel and the tensile wave keeps its speed (without it,
    ``c sqrt(M (M - epsilon M_f))``), while the repulsion of a closing pair, growing as
    ``f_ij^n``, stays; the weight is still symmetric, so AS-4 still books the pair's power.
    The pair force is antisymmetric, so momentum is kept exactly, and AS-4 is its power
    shared equally by the pair, so the semi-discrete equations keep the total energy.  In
    axisymmetry (``R`` from the record's ``A = |r| sigma / rho``, so ``rho R`` is ``|r|`` times
    the artificial stress, as ``Q = rho A`` is the stress's) the pair takes the form of the
    stress term below, ``dv_i/dt += 1/rho_i sum_j V_j f_ij^n (rho_i R_i + rho_j R_j) . grad
    W_ij`` and ``de_i/dt -= 1/(2 rho_i) sum_j V_j f_ij^n v_ij . (rho_i R_i + rho_j R_j) .
    grad W_ij``: the pair force ``V_i V_j f^n (...) . grad W_ij`` is antisymmetric (axial
    momentum kept) and AS-4 its power shared equally; the artificial stress acts in the r-z
    plane only (no hoop part: no pair of particles lies along the hoop direction).  With
    the kernel gradient correction of the forces it stays on the uncorrected ``grad W_ij``: a
    repulsion between neighbours, which needs no consistency, and its antisymmetry and energy
    balance need no correction matrix.

    Axisymmetry (``AXISYMMETRIC``; x the radius r, y the axis z; docs/modelling.md): with
    ``rho = rho_m r`` (the mass per radian and unit area of the r-z plane, which the 2D
    continuity equation keeps exactly), ``V_j = m_j / rho_j`` (particle j's area in the r-z
    plane) and ``Q = |r| sigma``, the momentum equation in cylindrical coordinates times r,
    ``rho dv/dt = div_rz(Q) - sigma_tt e_r``, is discretised in the symmetric form

        dv_i/dt = 1/rho_i sum_j V_j (Q_i + Q_j) . grad W_ij  -  sigma_tt,i M_i / rho_i e_r
        de_i/dt = 1/rho_i Q_i : sum_j V_j v_ji (x) grad W_ij + sigma_tt,i M_i v_r,i / rho_i
        dS_i/dt += 2 mu (M_i v_r,i / r_i) (e_t e_t - I/3)

    (``v_r / r`` in place of ``M_i v_r / r_i`` in ``dS`` with the velocity-gradient
    correction, which makes the rest of the strain rate exact for a linear field), with
    ``M_i = sum_j V_j (|r_j| - r_i) dW_ij/dr_i`` over the same neighbours, the sums' own
    estimate of ``dr/dr``: the pair term gives ``sigma M_i / rho_i e_r`` for a uniform stress
    where the support is full, so the hoop term cancels it exactly for ``sigma_rr =
    sigma_tt``, next to the axis too (with 1 in its place a uniform pressure pushed the
    particles there by ``P (M_i - 1) / rho_i``).  The pair force ``V_i V_j (Q_i + Q_j)
    grad W_ij`` is antisymmetric (axial momentum kept), the energy rate is its adjoint and
    the hoop power likewise, so the total energy per radian is kept exactly.  A ghost across
    the axis (``r < 0``) carries its source's stress mirrored, so ``|r|`` makes its pair with
    a particle the mirror of the pair of their sources, and the energy stays exact; the
    signed ``r``, which continues ``r sigma`` smoothly across the axis, broke that (a rod's
    energy error 4e-3 against 6e-5, docs/modelling.md).  Contact between bodies takes the
    same form with the normal stress (or pressure) for ``sigma``.

    The compatible energy update (``COMPATIBLE_ENERGY``, ``time.energy_update =
    "compatible"``; Owen 2014, Int. J. Numer. Meth. Fluids 75:749): every energy term above
    (the stress work ``A_i : T``, the viscous heating, AS-4, the contact work and the hoop
    power) reads the velocity differences of the *work velocity* ``w`` (record column ``W``),
    and nothing else does: the forces, the continuity sum and the velocity gradient read
    ``v``.  Each energy term is its pair force's power shared between the pair, so with ``w``
    the step's mean velocity ``(v(t) + v(t + dt)) / 2`` and the forces of the step's
    evaluation, ``sum_i m_i de_i dt`` is minus the kinetic energy the step gave those
    forces, exactly (:meth:`impactsph.solver.Solver.work_rates`).  The ordinary evaluations
    set ``w = v``."""
    shear = table[material[i], SHEAR]
    Pi_ = P[p]
    xi0 = record_position(Pi_, 0)
    vi0 = Pi_[V]
    xi1 = record_position(Pi_, 1) if DIM > 1 else 0.0
    vi1 = Pi_[V + 1] if DIM > 1 else 0.0
    xi2 = record_position(Pi_, 2) if DIM > 2 else 0.0
    vi2 = Pi_[V + 2] if DIM > 2 else 0.0
    hi, ci, rhoi, bi = Pi_[H], Pi_[C], Pi_[RHO], Pi_[BODY]
    # the velocity the energy terms read: the work velocity with the compatible update
    wi0 = Pi_[W] if COMPATIBLE_ENERGY else vi0
    wi1 = (Pi_[W + 1] if COMPATIBLE_ENERGY else vi1) if DIM > 1 else 0.0
    wi2 = (Pi_[W + 2] if COMPATIBLE_ENERGY else vi2) if DIM > 2 else 0.0
    # accumulators: sum m_j grad W (same body); sum m_j A_j . grad W;
    # contact and viscous accelerations; L; T = sum m_j v_ij (x) grad W; energies
    G0 = G1 = G2 = 0.0
    a0 = a1 = a2 = 0.0
    k0 = k1 = k2 = 0.0
    w0 = w1 = w2 = 0.0
    f0 = f1 = f2 = 0.0  # viscous push across bodies (part of the contact force)
    # a scheme with a switch (VISCOSITY_FACTOR): the particle's factor f_i, and the viscous
    # acceleration of the unscaled Pi_ij, which the switch reads
    fi = Pi_[VF] if VISCOSITY_FACTOR else 1.0
    wr0 = wr1 = wr2 = 0.0
    L00 = L01 = L02 = L10 = L11 = L12 = L20 = L21 = L22 = 0.0
    T00 = T01 = T02 = T10 = T11 = T12 = T20 = T21 = T22 = 0.0
    # the kernel gradient correction's moment matrix B = -sum_j V_j r_ij (x) grad W_ij
    # (GRADIENT_CORRECTION only; see correct_velocity_gradient)
    B00 = B01 = B02 = B11 = B12 = B22 = 0.0  # (B is symmetric)
    # the artificial stress (ARTIFICIAL_STRESS > 0 only): the particle's own R_i, the sums
    # sum m_j f_ij^n (R_i + R_j) . grad W_ij and sum m_j f_ij^n v_ij . (R_i + R_j) . grad W_ij
    ri00 = ri01 = ri02 = ri11 = ri12 = ri22 = 0.0
    if ARTIFICIAL_STRESS > 0.0:
        ri00 = Pi_[R00]
        if DIM > 1:
            ri01 = Pi_[R01]
            ri11 = Pi_[R11]
        if DIM > 2:
            ri02 = Pi_[R02]
            ri12 = Pi_[R12]
            ri22 = Pi_[R22]
    x0 = x1 = x2 = 0.0
    xe = 0.0
    inv_rho_i = 1.0 / rhoi if AXISYMMETRIC else 1.0
    mr = 0.0  # axisymmetry: -M_i = sum_j V_j (r_i - r_j) dW_ij/dr_i (same body)
    de_contact = 0.0
    de_v = 0.0
    count = 0
    n_other = 0  # pairs within the support with another body or a wall ghost
    # First loop, every pair, which LLVM vectorises over the neighbours (4 pairs at a time
    # with AVX2; issue 16, benchmarks/README.md) under pair_pass's flags (PAIR_FASTMATH, no
    # zero-division checks).  What it needs, each found by measurement: no branch (the
    # support and the body are masks: ``fq`` is 0 outside the support, ``fs`` also for a
    # neighbour of another body, and every same-body term is linear in the kernel gradient,
    # so weighting it by ``fs`` drops the pair exactly; pairs of the list's skin cost a masked
    # evaluation); no zero-division check (numba's default error model puts a branch on each
    # division); the neighbour's columns read as ``P[j, col]`` (a row view ``P[j]`` stops the
    # vectoriser); and reassociation on the sums, which then run as one partial sum per
    # vector lane (results move at round-off: tests/test_pinned_results.py).
    first, last = support_range(xi0, xi1, xi2, hi, P, offsets, indices, p, listed, starts,
                                filter_skin)
    for k in range(first, last):
        j = listed[k]  # P[j, col], not a row view: the view stops the vectoriser
        d0, d1, d2, r2, h_ij, inv_h, q2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)
        inside = (q2 < 4.0) & (r2 > 0.0)
        q = math.sqrt(q2)
        fq = cubic_spline_gradient_factor(q, inv_h, DIM) if inside else 0.0
        same_body = P[j, BODY] == bi
        fs = fq if same_body else 0.0
        count += 1 if inside else 0
        n_other += 0 if same_body or not inside else 1
        s0 = fs * d0  # the same-body kernel gradient
        s1 = fs * d1
        s2 = fs * d2
        u0 = vi0 - P[j, V]
        u1 = vi1 - P[j, V + 1] if DIM > 1 else 0.0
        u2 = vi2 - P[j, V + 2] if DIM > 2 else 0.0
        vr = u0 * d0 + u1 * d1 + u2 * d2
        if COMPATIBLE_ENERGY:  # the energy terms' velocity difference: the work velocity's
            z0 = wi0 - P[j, W]
            z1 = wi1 - P[j, W + 1] if DIM > 1 else 0.0
            z2 = wi2 - P[j, W + 2] if DIM > 2 else 0.0
            zr = z0 * d0 + z1 * d1 + z2 * d2
        else:
            z0, z1, z2 = u0, u1, u2
            zr = vr
        m_j = np.float64(P[j, M])  # float32 records: its products with them in float64
        volume_j = np.float64(P[j, VOL])
        if GRADIENT_CORRECTION:
            B00 -= volume_j * d0 * s0
            if DIM > 1:
                B01 -= volume_j * d0 * s1
                B11 -= volume_j * d1 * s1
            if DIM > 2:
                B02 -= volume_j * d0 * s2
                B12 -= volume_j * d1 * s2
                B22 -= volume_j * d2 * s2
        # the kernel gradient that the neighbour's stress A_j meets: C_j grad W_ij with the
        # correction of the forces, grad W_ij otherwise
        if FORCE_CORRECTION:
            t0 = P[j, CM0] * s0
            t1 = 0.0
            t2 = 0.0
            if DIM > 1:
                t0 += P[j, CM0 + 1] * s1
                t1 = P[j, CM0 + DIM] * s0 + P[j, CM0 + DIM + 1] * s1
            if DIM > 2:
                t0 += P[j, CM0 + 2] * s2
                t1 += P[j, CM0 + DIM + 2] * s2
                t2 = (P[j, CM0 + 2 * DIM] * s0 + P[j, CM0 + 2 * DIM + 1] * s1
                      + P[j, CM0 + 2 * DIM + 2] * s2)
        else:
            t0, t1, t2 = s0, s1, s2
        if ARTIFICIAL_STRESS > 0.0 and AXISYMMETRIC:  # V_j f (rho_i R_i + rho_j R_j) / rho_i
            fw = artificial_stress_weight(q) - AS_COMPENSATION
            wo = volume_j * fw  # the own R_i's weight
            wn = m_j * fw * inv_rho_i  # the neighbour's R_j's
            r00 = wo * ri00 + wn * P[j, R00]
            r01 = wo * ri01 + wn * P[j, R01]
            r11 = wo * ri11 + wn * P[j, R11]
            e0 = r00 * s0 + r01 * s1
            e1 = r01 * s0 + r11 * s1
            x0 += e0
            x1 += e1
            xe += z0 * e0 + z1 * e1
        elif ARTIFICIAL_STRESS > 0.0:  # on the uncorrected grad W_ij (docs/stabilisation.md)
            mf = m_j * (artificial_stress_weight(q) - AS_COMPENSATION)
            e0 = (ri00 + P[j, R00]) * s0
            e1 = e2 = 0.0
            if DIM > 1:
                r01 = ri01 + P[j, R01]
                e0 += r01 * s1
                e1 = r01 * s0 + (ri11 + P[j, R11]) * s1
            if DIM > 2:
                r02 = ri02 + P[j, R02]
                r12 = ri12 + P[j, R12]
                e0 += r02 * s2
                e1 += r12 * s2
                e2 = r02 * s0 + r12 * s1 + (ri22 + P[j, R22]) * s2
            x0 += mf * e0
            x1 += mf * e1
            x2 += mf * e2
            xe += mf * (z0 * e0 + z1 * e1 + z2 * e2)
        # the weight of the particle's own A_i: m_j (A_i = sigma_i / rho_i^2), or in
        # axisymmetry V_j (A_i = Q_i / rho_i)
        w_j = volume_j if AXISYMMETRIC else m_j
        if AXISYMMETRIC:
            mr += volume_j * (xi0 - abs(neighbour_position(P, j, 0))) * s0
        # the weighted gradients each serve several sums: ws = w_j s (G's pair term, and T's
        # with z), mt = m_j t (the neighbour's stress meets it); without the correction of
        # the forces and axisymmetry they are the same products
        ws0 = w_j * s0
        mt0 = m_j * t0
        G0 += ws0
        sa0 = P[j, A00] * mt0  # this pair's terms of the sums a (the neighbour's stress)
        sa1 = sa2 = 0.0
        L00 += velocity_gradient_pair(volume_j, u0, s0)
        T00 += z0 * ws0
        if DIM > 1:
            ws1 = w_j * s1
            mt1 = m_j * t1
            G1 += ws1
            sa0 += P[j, A01] * mt1
            sa1 = P[j, A01] * mt0 + P[j, A11] * mt1
            L01 += velocity_gradient_pair(volume_j, u0, s1)
            L10 += velocity_gradient_pair(volume_j, u1, s0)
            L11 += velocity_gradient_pair(volume_j, u1, s1)
            T01 += z0 * ws1
            T10 += z1 * ws0
            T11 += z1 * ws1
        if DIM > 2:
            ws2 = w_j * s2
            mt2 = m_j * t2
            G2 += ws2
            sa0 += P[j, A02] * mt2
            sa1 += P[j, A12] * mt2
            sa2 = P[j, A02] * mt0 + P[j, A12] * mt1 + P[j, A22] * mt2
            L02 += velocity_gradient_pair(volume_j, u0, s2)
            L12 += velocity_gradient_pair(volume_j, u1, s2)
            L20 += velocity_gradient_pair(volume_j, u2, s0)
            L21 += velocity_gradient_pair(volume_j, u2, s1)
            L22 += velocity_gradient_pair(volume_j, u2, s2)
            T02 += z0 * ws2
            T12 += z1 * ws2
            T20 += z2 * ws0
            T21 += z2 * ws1
            T22 += z2 * ws2
        a0 += sa0
        if DIM > 1:
            a1 += sa1
        if DIM > 2:
            a2 += sa2
        vr_visc = vr
        if VELOCITY_RECONSTRUCTION:  # the jump at the midpoint (reconstruction.py), same body
            vr_rec = reconstructed_approach(vr, projected_slope(P, p, LV0, d0, d1, d2),
                                            projected_slope(P, j, LV0, d0, d1, d2),
                                            visc_params[3])
            vr_visc = vr_rec if same_body else vr
        pi_ij = pair_viscosity(visc_kind, vr_visc, r2, h_ij, 0.5 * (ci + P[j, C]),
                               0.5 * (rhoi + P[j, RHO]), visc_params)
        # grad W_ij = fq r_ij: each viscous term below is a multiple of fq r_ij
        if VISCOSITY_FACTOR:  # the switch: Pi_ij (f_i + f_j) / 2, symmetric in i, j
            raw = viscous_acceleration_pair(m_j, pi_ij, fq)
            wr0 += raw * d0
            wr1 += raw * d1
            wr2 += raw * d2
            pi_ij *= 0.5 * (fi + P[j, VF])
        visc = viscous_acceleration_pair(m_j, pi_ij, fq)  # 0 if receding
        w0 += visc * d0
        w1 += visc * d1
        w2 += visc * d2
        # the viscous heating 1/2 m_j Pi_ij z_ij . grad W_ij (viscous_heating_pair) is
        # -visc (z_ij . r_ij) / 2: two values and a constant.  (Written as the product of
        # 1/2, m_j, Pi_ij, fq and z_ij . r_ij, a chain that reassociation may order by where
        # its factors are defined, the serial and the threaded passes differed at round-off:
        # tests/test_threads.py.)
        de_v += -0.5 * visc * zr
    # the continuity sum of eq 22 over the same body, sum_j V_j v_ij . grad W_ij, is minus
    # the trace of the velocity gradient's sum (continuity_pair and velocity_gradient_pair
    # are the same products), so the loop does not form it (results move at round-off)
    cont = -(L00 + L11 + L22)
    # Only where the particle has neighbours of another body or wall ghosts within the
    # support (a few particles at a contact surface), and the contact force is tracked: the
    # viscous push across bodies, the first loop's viscous term of those pairs again.  A loop
    # of its own, not a part of the contact loop below: there its values were live beside
    # the contact's and the first loop's sums, and the 3D CUDA pair kernel took 182 registers
    # a thread (2 blocks of 128 a multiprocessor) instead of 166 (3 blocks; ptxas for sm_90,
    # benchmarks/gpu_registers.py; benchmarks/README.md, "The GPU pair kernel's registers").
    # (its names carry v_, to keep them apart from the first loop's)
    track_contact = contact_force.shape[0] > 0
    for v_k in range(offsets[p], offsets[p + 1] if n_other > 0 and track_contact
                     else offsets[p]):
        v_Pj = P[indices[v_k]]
        if v_Pj[BODY] == bi:
            continue
        v_d0, v_d1, v_d2, v_r2, v_h_ij, v_inv_h, v_q2 = pair_separation(Pi_, v_Pj)
        if v_q2 >= 4.0 or v_r2 == 0.0:
            continue
        v_fq = cubic_spline_gradient_factor(math.sqrt(v_q2), v_inv_h, DIM)
        v_u0 = vi0 - v_Pj[V]
        v_u1 = vi1 - v_Pj[V + 1] if DIM > 1 else 0.0
        v_u2 = vi2 - v_Pj[V + 2] if DIM > 2 else 0.0
        v_pi = pair_viscosity(visc_kind, v_u0 * v_d0 + v_u1 * v_d1 + v_u2 * v_d2, v_r2,
                              v_h_ij, 0.5 * (ci + v_Pj[C]), 0.5 * (rhoi + v_Pj[RHO]),
                              visc_params)
        if VISCOSITY_FACTOR:
            v_pi *= 0.5 * (fi + v_Pj[VF])
        v_visc = viscous_acceleration_pair(np.float64(v_Pj[M]), v_pi, v_fq)
        f0 += v_visc * v_d0
        f1 += v_visc * v_d1
        f2 += v_visc * v_d2
    # Second loop, only where the particle has neighbours of another body or wall ghosts
    # within the support: compression-only contact.
    # (its names carry c_, to keep them apart from the first loop's)
    for c_k in range(offsets[p], offsets[p + 1] if n_other > 0 else offsets[p]):
        c_Pj = P[indices[c_k]]
        if c_Pj[BODY] == bi:
            continue
        c_d0, c_d1, c_d2, c_r2, c_h_ij, c_inv_h, c_q2 = pair_separation(Pi_, c_Pj)
        if c_q2 >= 4.0 or c_r2 == 0.0:
            continue
        c_fq = cubic_spline_gradient_factor(math.sqrt(c_q2), c_inv_h, DIM)
        c_g0 = c_fq * c_d0
        c_g1 = c_fq * c_d1
        c_g2 = c_fq * c_d2
        c_u0 = vi0 - c_Pj[V]
        c_u1 = vi1 - c_Pj[V + 1] if DIM > 1 else 0.0
        c_u2 = vi2 - c_Pj[V + 2] if DIM > 2 else 0.0
        c_vg = c_u0 * c_g0 + c_u1 * c_g1 + c_u2 * c_g2
        c_wg = c_vg  # the energy term's: with the work velocity under the compatible update
        if COMPATIBLE_ENERGY:
            c_wg = (wi0 - c_Pj[W]) * c_g0
            if DIM > 1:
                c_wg += (wi1 - c_Pj[W + 1]) * c_g1
            if DIM > 2:
                c_wg += (wi2 - c_Pj[W + 2]) * c_g2
        c_volume_j = c_Pj[VOL]
        c_sn_i, c_sn_j = contact_traction(Pi_, c_Pj, c_d0, c_d1, c_d2, c_r2, normal_stress)
        if AXISYMMETRIC:  # V_i V_j (Q_i + Q_j) with Q = rho sn: per unit mass of i
            c_s_ij = rhoi * c_sn_i + c_Pj[RHO] * c_sn_j
            c_weight_j = c_volume_j / rhoi
            c_own_j = c_volume_j
        else:
            c_s_ij = c_sn_i + c_sn_j
            c_weight_j = c_own_j = c_Pj[M]
        if in_contact(c_s_ij, c_vg):
            cont += continuity_pair(1.0, c_volume_j, c_vg)
            c_push = contact_acceleration_pair(c_weight_j, c_s_ij, 1.0)
            k0 += c_push * c_g0
            k1 += c_push * c_g1
            k2 += c_push * c_g2
            de_contact += contact_work_pair(c_own_j, c_sn_i, c_s_ij, c_wg)
    # A_i applied to the regrouped sums
    if FORCE_CORRECTION:  # the particle's own C_i: G <- C_i G, T <- T C_i^T, L <- L C_i^T
        G0, G1, G2 = corrected(Pi_, G0, G1, G2)
        T00, T01, T02 = corrected(Pi_, T00, T01, T02)
        T10, T11, T12 = corrected(Pi_, T10, T11, T12)
        T20, T21, T22 = corrected(Pi_, T20, T21, T22)
        L00, L01, L02 = corrected(Pi_, L00, L01, L02)
        L10, L11, L12 = corrected(Pi_, L10, L11, L12)
        L20, L21, L22 = corrected(Pi_, L20, L21, L22)
    G = (G0, G1, G2)
    acc = (a0, a1, a2)
    kc = (k0, k1, k2)
    wv = (w0, w1, w2)
    wr = (wr0, wr1, wr2) if VISCOSITY_FACTOR else wv
    fv = (f0, f1, f2)
    Lt = ((L00, L01, L02), (L10, L11, L12), (L20, L21, L22))
    Tt = ((T00, T01, T02), (T10, T11, T12), (T20, T21, T22))
    xs = (x0, x1, x2)
    m_i = Pi_[M]
    de_s = de_contact
    if ARTIFICIAL_STRESS > 0.0:
        de_s -= 0.5 * xe
    inv_own = 1.0 / rhoi if AXISYMMETRIC else 1.0  # sum m_j A_j grad W_ij over rho_i
    for a in range(DIM):
        s = acc[a] * inv_own + kc[a]
        for b in range(DIM):
            A_ab = Pi_[SYM[a][b]]
            s += A_ab * G[b]
            de_s -= A_ab * Tt[a][b]
            L[a, b] = Lt[a][b]
        if ARTIFICIAL_STRESS > 0.0:
            s += xs[a]
        dv[i, a] = s + wv[a]
        if P.shape[1] > U:  # the rows carry u (a correction or a switch reads it)
            P[p, U + a] = wr[a]
        if track_contact:
            contact_force[i, a] = m_i * (kc[a] + fv[a])
    if GRADIENT_CORRECTION:  # B is symmetric: its lower triangle is its upper
        correct_velocity_gradient(L, B00, B01, B02, B01, B11, B12, B02, B12, B22)
    if L_sorted.shape[0] > 0:
        for a in range(DIM):
            for b in range(DIM):
                L_sorted[p, a, b] = L[a, b]
    drho[i] = rhoi * cont
    if AXISYMMETRIC:  # the hoop terms: rho dv_r/dt -= sigma_tt M, rho de/dt += sigma_tt M v_r
        hoop = Pi_[HOOP] * -mr
        dv[i, 0] -= hoop
        de_s += hoop * wi0
    de[i] = de_s + de_v
    de_visc[i] = de_v
    pair_count[i] = count
    stress_rate(L, S[i], shear, dS[i])
    if AXISYMMETRIC:  # the hoop strain rate in the deviatoric rate: v_r / r where the
        # velocity gradient is corrected (exact for a linear field), else M v_r / r, the
        # same sums' estimate
        g = 2.0 * shear * vi0 / Pi_[RADIUS]
        if not GRADIENT_CORRECTION:
            g *= -mr
        dS[i, UPPER[0][0]] -= g / 3.0
        dS[i, UPPER[1][1]] -= g / 3.0
        dS[i, UPPER[2][2]] += 2.0 * g / 3.0


#: how many sorted positions ahead the pair pass asks the caches for a particle's rows that it
#: reads and writes by number (:func:`impactsph.physics.prefetch.prefetch_row`)
PREFETCH_AHEAD = 4
#: from how many rows on it does so: below, the arrays sit in a core's cache (16,384 rows of
#: the stress alone are 1.2 MB) and the hints cost the Taylor bar's pass 3-5%
PREFETCH_ROWS = 16384
#: the cache lines a packed record's row can touch (a row of float64 at any offset in a line)
RECORD_LINES = (RECORD_WIDTH * 8 + 2 * 63) // 64


@JIT(inline="always", cache=True)
def particle_ahead(order, p, n_active, far):
    """The active particle :data:`PREFETCH_AHEAD` sorted positions after ``p``, whose rows a
    pass that reads and writes by number asks the caches for; -1 where there is none (a
    ghost, the list's end) or where the rows are few (``far`` False)."""
    if not far:
        return -1
    ahead = order[min(p + PREFETCH_AHEAD, order.shape[0] - 1)]
    return ahead if ahead < n_active else -1


#: plane stress: the out-of-plane stress ``sigma_zz`` is zeroed to ``PLANE_STRESS_TOLERANCE``
#: times the bulk modulus (1e-13 K: 0.02 Pa for steel), in at most ``PLANE_STRESS_ITERATIONS``
#: secant steps (:func:`plane_stress_stage`; two to four on the paper's cantilever)
PLANE_STRESS_TOLERANCE = 1e-13
PLANE_STRESS_ITERATIONS = 40


@JIT(inline="always", cache=True)
def thickness_trial(i, z, dt, rho, e, S, state0, state, row, t00, t01, t02, t11, t12, t22):
    """Plane stress: the stage of particle ``i`` with thickness strain rate ``z``: the trial
    deviator ``t`` (the in-plane rates' update) plus ``2 mu dt z (e_z e_z - I/3)``, the
    material state restored, ``tau = tau0 exp(dt z)``, the pressure at ``rho / tau`` and the
    strength model's return.  Returns ``(sigma_zz, P, rho / tau, w)``: the carried
    out-of-plane stress ``(1 - D) S_zz - P_carried``, the pressure, the material's density
    and the plastic work."""
    g = 2.0 * row[SHEAR] * dt * z
    S[i, 0, 0] = t00 - g / 3.0
    S[i, 1, 1] = t11 - g / 3.0
    S[i, 2, 2] = t22 + 2.0 * g / 3.0
    S[i, 0, 1] = S[i, 1, 0] = t01
    S[i, 0, 2] = S[i, 2, 0] = t02
    S[i, 1, 2] = S[i, 2, 1] = t12
    for c in range(state0.shape[1]):  # the case's width (TableLayout.state_width_of)
        state[i, c] = state0[i, c]
    st = state[i]
    tau = state0[i, THICKNESS_RATIO] * math.exp(dt * z)
    st[THICKNESS_RATIO] = tau
    rho_m = rho[i] / tau
    pr = eos_pressure(int(row[EOS_KIND]), rho_m, e[i], row[RHO0], row[BULK], row[EOS_PARAMS:])
    work = strength_return(int(row[STRENGTH_KIND]), S[i], rho_m, pr, row[SHEAR],
                           row[STRENGTH_PARAMS:DAMAGE_PARAMS], st,
                           st[STRENGTH_STATE:DAMAGE_STATE], dt)
    intact = 1.0 - st[DAMAGE]
    carried = pr * intact if pr < 0.0 else pr
    return intact * S[i, 2, 2] - carried, pr, rho_m, work


@JIT(inline="always", cache=True)
def plane_stress_stage(i, dt, rho, e, S, state0, state, row):
    """Plane stress (``sigma_zz = 0``) for one integrator stage of particle ``i``, whose
    in-plane quantities are already advanced: the thickness strain rate ``z = d ln t / dt``
    found by the secant method such that, after the equation of state and the strength
    model's return, the carried ``sigma_zz = (1 - D) S_zz - P`` is zero.

    The residual rises with ``z`` (a thicker particle is less dense, its pressure lower and
    its ``S_zz`` higher), with slope between ``dt K`` (fully plastic) and ``dt (K + 4 mu/3)``
    (elastic); the first step uses the elastic slope, so an elastic stage converges in one
    step of the secant beyond it.  Any equation of state and strength model works unchanged
    (the return is 3D, its ``S_zz`` free): the iteration on the out-of-plane strain that
    general-purpose FE codes use for plane stress, rather than a return written for plane
    stress alone.  Returns ``(P, rho / tau, w)``."""
    t00, t01, t02 = S[i, 0, 0], S[i, 0, 1], S[i, 0, 2]
    t11, t12, t22 = S[i, 1, 1], S[i, 1, 2], S[i, 2, 2]
    tolerance = PLANE_STRESS_TOLERANCE * row[BULK]
    z_a = 0.0
    f_a, pr, rho_m, work = thickness_trial(i, z_a, dt, rho, e, S, state0, state, row,
                                           t00, t01, t02, t11, t12, t22)
    if abs(f_a) <= tolerance or dt == 0.0:
        return pr, rho_m, work
    elastic = dt * (row[BULK] + 4.0 * row[SHEAR] / 3.0)
    z_b = -f_a / elastic
    for _ in range(PLANE_STRESS_ITERATIONS):
        f_b, pr, rho_m, work = thickness_trial(i, z_b, dt, rho, e, S, state0, state, row,
                                               t00, t01, t02, t11, t12, t22)
        if abs(f_b) <= tolerance or f_b == f_a:
            break
        slope = (f_b - f_a) / (z_b - z_a)
        if not slope > 0.0:  # never seen (the residual rises); a step of the elastic slope
            slope = elastic
        z_a, f_a = z_b, f_b
        z_b -= f_b / slope
    return pr, rho_m, work


@JIT(inline="always", cache=True)
def friction_particle(p, i, P, offsets, indices, visc_kind, visc_params, mu, real_bodies,
                      normal_stress, dv, de, contact_force):
    """Coulomb friction between bodies on the active particle ``i`` at sorted position ``p``
    (:mod:`impactsph.physics.contact`): over its neighbours of another body (``body <
    real_bodies``: not a rigid wall's ghost, which has its own friction), the pushing pairs'
    friction added to ``dv[i]``, their heat to ``de[i]`` and ``m_i`` times the force to
    ``contact_force[i]``.  The push is the pair pass's: the contact traction (``normal_stress``
    or the pressures) and the artificial viscosity of an approaching pair, as a wall's
    friction takes the whole push of its ghosts."""
    Pi_ = P[p]
    bi, ci = Pi_[BODY], Pi_[C]
    a0 = a1 = a2 = 0.0
    heat = 0.0
    for k in range(offsets[p], offsets[p + 1]):
        Pj = P[indices[k]]
        bj = Pj[BODY]
        if bj == bi or bj >= real_bodies:
            continue
        d0, d1, d2, r2, h_ij, inv_h, q2 = pair_separation(Pi_, Pj)
        if q2 >= 4.0 or r2 == 0.0:
            continue
        sn_i, sn_j = contact_traction(Pi_, Pj, d0, d1, d2, r2, normal_stress)
        s_ij = sn_i + sn_j
        u0 = Pi_[V] - Pj[V]
        u1 = Pi_[V + 1] - Pj[V + 1] if DIM > 1 else 0.0
        u2 = Pi_[V + 2] - Pj[V + 2] if DIM > 2 else 0.0
        vr = u0 * d0 + u1 * d1 + u2 * d2
        pi_ij = pair_viscosity(visc_kind, vr, r2, h_ij, 0.5 * (ci + Pj[C]),
                               0.5 * (Pi_[RHO] + Pj[RHO]), visc_params)  # 0 if receding
        if VISCOSITY_FACTOR:  # as the pair pass applies it
            pi_ij *= 0.5 * (Pi_[VF] + Pj[VF])
        normal = max(s_ij, 0.0) + pi_ij
        if normal <= 0.0:
            continue
        r = math.sqrt(r2)
        push = Pj[M] * normal * abs(cubic_spline_gradient_factor(math.sqrt(q2), inv_h, DIM)) * r
        along = vr / r2
        t0 = u0 - along * d0
        t1 = u1 - along * d1
        t2 = u2 - along * d2
        slip2 = t0 * t0 + t1 * t1 + t2 * t2
        f = friction_factor(mu, push, slip2, FRICTION_REGULARISATION * 0.5 * (ci + Pj[C]))
        a0 -= f * t0
        a1 -= f * t1
        a2 -= f * t2
        heat += 0.5 * f * slip2
    acc = (a0, a1, a2)
    track = contact_force.shape[0] > 0
    for a in range(DIM):
        dv[i, a] += acc[a]
        if track:
            contact_force[i, a] += Pi_[M] * acc[a]
    de[i] += heat


@JIT(inline="always", cache=True)
def advance_particle(i, dt, x0, v0, rho0, e0, S0, pw0, state0, hg0, v_rate, dv, drho, de, dS,
                     dhg, clamped, material, table, h, x, v, rho, e, S, plastic_work, state, hg,
                     restore=True):
    """One integrator stage of particle ``i``: ``y = y0 + dt ydot`` with ``xdot = v_rate``
    (a clamped particle keeps ``v = 0``), the material state restored to its value at the
    start of the step, then the strength model's return map and the specific plastic work
    ``w`` it dissipates, the temperature raised by ``beta w / c_p`` (the Taylor-Quinney
    factor over the specific heat), and the damage model's update.  ``v_rate`` may be ``v``
    itself: the position is advanced before the velocity.  The deviator's start ``S0`` and
    rate ``dS`` are symmetric tensors' six components (:data:`UPPER`), so ``S`` comes out
    exactly symmetric.  ``restore`` False: the material state already holds its start (the
    stage has just copied it into ``state0``), so it is not copied back: the Taylor bar's and
    the cantilever's predictor stage 0.94-0.97 of its time (``bench_pass_ab.py --passes
    stage``), the same bits."""
    for a in range(DIM):
        x[i, a] = x0[i, a] + dt * v_rate[i, a]
        v[i, a] = 0.0 if clamped[i] else v0[i, a] + dt * dv[i, a]
    rho[i] = rho0[i] + dt * drho[i]
    e[i] = e0[i] + dt * de[i]
    for a in range(3):  # S0 and dS: six components each (a symmetric tensor's upper triangle)
        for b in range(3):
            S[i, a, b] = S0[i, UPPER[a][b]] + dt * dS[i, UPPER[a][b]]
    if restore:  # the kept columns: those a model changes (material_state_kept)
        for c in range(state0.shape[1]):
            state[i, c] = state0[i, c]
    for a in range(hg.shape[1]):  # the hourglass acceleration (no columns when it is off)
        hg[i, a] = hg0[i, a] + dt * dhg[i, a]
    k = material[i]
    row = table[k]
    st = state[i]
    eps_before = st[EQUIVALENT_PLASTIC_STRAIN]
    if PLANE_STRESS:
        pr, rho_m, work = plane_stress_stage(i, dt, rho, e, S, state0, state, row)
    else:
        if AXISYMMETRIC:  # rho is the mass per radian and area: rho_m = rho / r
            st[THICKNESS_RATIO] = max(x[i, 0], AXIS_FLOOR * h[i])
            rho_m = rho[i] / st[THICKNESS_RATIO]
        else:
            rho_m = rho[i]
        pr = eos_pressure(int(row[EOS_KIND]), rho_m, e[i], row[RHO0], row[BULK],
                          row[EOS_PARAMS:])
        work = strength_return(int(row[STRENGTH_KIND]), S[i], rho_m, pr, row[SHEAR],
                               row[STRENGTH_PARAMS:DAMAGE_PARAMS], st,
                               st[STRENGTH_STATE:DAMAGE_STATE], dt)
    plastic_work[i] = pw0[i] + work
    st[TEMPERATURE] += row[HEAT_PER_WORK] * work
    damage_update(int(row[DAMAGE_KIND]), S[i], pr, rho_m, h[i], dt,
                  st[EQUIVALENT_PLASTIC_STRAIN] - eps_before, row, row[DAMAGE_PARAMS:], st,
                  st[DAMAGE_STATE:])


@JIT(inline="always", cache=True)
def unexplained_velocity(a, p, q, P, L_sorted, d0, d1, d2):
    """Component ``a`` of ``v_pq - (L_p + L_q) r_pq / 2`` for the records at sorted positions
    ``p``, ``q`` (``r_pq = (d0, d1, d2)``)."""
    e = P[p, V + a] - P[q, V + a] - 0.5 * (L_sorted[p, a, 0] + L_sorted[q, a, 0]) * d0
    if DIM > 1:
        e -= 0.5 * (L_sorted[p, a, 1] + L_sorted[q, a, 1]) * d1
    if DIM > 2:
        e -= 0.5 * (L_sorted[p, a, 2] + L_sorted[q, a, 2]) * d2
    return e


@JIT(inline="always", cache=True)
def hourglass_particle(p, i, P, L_sorted, offsets, indices, material, table, zeta, hg, dv, de,
                       dhg, listed, starts, filter_skin):
    """Hourglass control of the active particle ``i`` at sorted position ``p``
    (docs/stabilisation.md).  The relative velocity of each neighbour ``j`` of the same body
    that the velocity gradients do not explain, ``e_ij = v_ij - (L_i + L_j) r_ij / 2`` (zero
    for a linear field, large for the zig-zag modes that the collocated gradient cannot see),
    enters the non-nested (Brookshaw) Laplacian, and the particle's hourglass acceleration
    ``hg_i`` (a state, integrated in time like the stress) grows at

        d hg_i/dt = zeta mu_i / rho_i  2 sum_j V_j e_ij (r_ij . grad W_ij) / (r_ij^2 + 0.01 h^2)

    an elastic restoring acceleration of shear stiffness ``zeta mu`` against the unexplained
    relative displacement, with a viscous part of time scale ``tau_ij = h_ij / c_shear``
    (``c_shear^2 = mu / rho_ij``), ``zeta mu / rho_i`` times the same Laplacian of
    ``tau_ij e_ij``, which damps the control's own grid-scale oscillation (the midpoint rule
    amplifies an undamped one).  Both are added to ``dv[i]`` and their power taken from the internal
    energy, so that the total energy is kept; the pair terms are antisymmetric within a body
    of one material, so momentum is kept too.  A material without shear stiffness gets no
    control (``dhg`` and the push stay zero)."""
    Pi_ = P[p]
    bi = Pi_[BODY]
    shear = table[material[i], SHEAR]
    if shear <= 0.0:  # a material without shear stiffness (the 1D bar, a fluid): no control
        for a in range(DIM):
            dhg[i, a] = 0.0
        return
    xi0 = record_position(Pi_, 0)
    xi1 = record_position(Pi_, 1) if DIM > 1 else 0.0
    xi2 = record_position(Pi_, 2) if DIM > 2 else 0.0
    hi, rhoi = Pi_[H], Pi_[RHO]
    half_over_shear = 0.5 / shear
    a0 = a1 = a2 = 0.0  # the Laplacian of e
    b0 = b1 = b2 = 0.0  # the Laplacian of tau e
    # one loop without branches, vectorised as particle_rates' first loop (the support and
    # the body as a mask on the pair's coefficient; hourglass_pass's flags)
    first, last = support_range(xi0, xi1, xi2, hi, P, offsets, indices, p, listed, starts,
                                filter_skin)
    for k in range(first, last):
        q = listed[k]
        d0, d1, d2, r2, h_ij, inv_h, q2 = neighbour_separation(xi0, xi1, xi2, hi, P, q)
        inside = (q2 < 4.0) & (r2 > 0.0) & (P[q, BODY] == bi)
        fq = cubic_spline_gradient_factor(math.sqrt(q2), inv_h, DIM) if inside else 0.0
        coef = 2.0 * P[q, VOL] * fq * r2 / (r2 + 0.01 * h_ij * h_ij)  # grad W = fq r_ij
        # the viscous part's time scale tau_ij = h_ij / c_shear, c_shear^2 = mu / rho_ij
        tau = h_ij * math.sqrt((rhoi + P[q, RHO]) * half_over_shear)
        tau = tau if inside else 0.0
        # a select after the loads, not a product with the mask (a ghost's velocity gradient
        # may be unset, not finite, and 0 * NaN is NaN), nor a load under a condition (which
        # stops the vectoriser)
        e0 = unexplained_velocity(0, p, q, P, L_sorted, d0, d1, d2)
        e0 = e0 if inside else 0.0
        a0 += coef * e0
        b0 += coef * tau * e0
        if DIM > 1:
            e1 = unexplained_velocity(1, p, q, P, L_sorted, d0, d1, d2)
            e1 = e1 if inside else 0.0
            a1 += coef * e1
            b1 += coef * tau * e1
        if DIM > 2:
            e2 = unexplained_velocity(2, p, q, P, L_sorted, d0, d1, d2)
            e2 = e2 if inside else 0.0
            a2 += coef * e2
            b2 += coef * tau * e2
    rate = zeta * shear / Pi_[RHO]
    acc = (a0, a1, a2)
    damped = (b0, b1, b2)
    work = 0.0
    for a in range(DIM):
        dhg[i, a] = rate * acc[a]
        push = hg[i, a] + rate * damped[a]
        dv[i, a] += push
        work += Pi_[V + a] * push
    de[i] -= work


# -- the CPU passes --------------------------------------------------------------------------


@JIT(parallel=PARALLEL_OPTION, cache=True, error_model=BODY_ERROR_MODEL)
def particle_pass(order, x, v, m, rho, e, S, carried, h, body, material, table, P):
    """Pass 1 over every row (ghosts included), in the list's order (``order[p]`` is the
    particle at sorted position ``p``), as the pair pass walks them: each thread writes the
    records it reads next (below :data:`PREFETCH_ROWS` rows; above,
    :func:`own_order_particle_pass`)."""
    for p in nb.prange(order.shape[0]):
        particle_record(p, order[p], x, v, m, rho, e, S, carried, h, body, material, table, P)


@JIT(parallel=PARALLEL_OPTION, cache=True, error_model=BODY_ERROR_MODEL)
def own_order_particle_pass(rank, x, v, m, rho, e, S, carried, h, body, material, table, P):
    """:func:`particle_pass` in the particles' own order, for :data:`PREFETCH_ROWS` rows and
    more: particle ``i``'s record goes to its sorted row ``rank[i]`` (the inverse of the
    list's ``order``, :attr:`impactsph.neighbours.NeighbourList.rank`), and the row a few
    particles ahead is asked of the caches (:func:`impactsph.physics.prefetch.prefetch_row`).
    So the state's columns are read in sequence; in the list's order the reads jump about
    the state, which took a 2D lattice of 1e5 particles 2.8-3.9 ms a pass against 1.0 ms in
    sequence.  Below that many rows, walking by rows is the better: on two threads the
    records a thread writes are then those it reads next, 3-5% of a small run's step
    (benchmarks/README.md, "The particle pass in the particles' order").  The same records
    either way."""
    n = rank.shape[0]
    for i in nb.prange(n):
        prefetch_row(P, rank[min(i + PREFETCH_AHEAD, n - 1)], RECORD_LINES, True)
        particle_record(rank[i], i, x, v, m, rho, e, S, carried, h, body, material, table, P)


@JIT(parallel=CHUNKED_OPTION, cache=True, nogil=True, **NOALIAS,
     fastmath=PAIR_FASTMATH, error_model="numpy")
def moment_pass(first, step, order, P, offsets, indices, starts, chunk_size):
    """The correction matrices of every row (FORCE_CORRECTION only), after the records.
    Compiled as :func:`pair_pass`, so that the neighbour loop of :func:`moment_correction`
    vectorises (one thread at 1e5 particles: 2D 23.2 -> 12.3 ms, 3D 100 -> 48 ms;
    benchmarks/README.md)."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        start = chunk * chunk_size
        stop = min((chunk + 1) * chunk_size, n)
        listed = chunk_listed(offsets, indices, start, stop)
        for p in range(start, stop):
            moment_correction(p, P, offsets, indices, listed, starts, SKIN_FILTER)


@JIT(parallel=CHUNKED_OPTION, cache=True, nogil=True, **NOALIAS,
     fastmath=PAIR_FASTMATH, error_model="numpy")
def gradient_pass(first, step, order, P, offsets, indices, starts, chunk_size):
    """The velocity gradients of every row into the records (VELOCITY_RECONSTRUCTION only),
    after the records and before the pair pass; compiled as :func:`moment_pass`."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        start = chunk * chunk_size
        stop = min((chunk + 1) * chunk_size, n)
        listed = chunk_listed(offsets, indices, start, stop)
        for p in range(start, stop):
            velocity_gradient_record(p, P, offsets, indices, listed, starts, SKIN_FILTER)


@JIT(parallel=CHUNKED_OPTION, cache=True, nogil=True, **NOALIAS,
     fastmath=PAIR_FASTMATH, error_model="numpy")
def pair_pass(first, step, n_active, order, P, offsets, indices, starts, visc_kind, visc_params,
              normal_stress, S, material, table, drho, dv, de, de_visc, contact_force,
              pair_count, dS, L_sorted, chunk_size):
    """Pass 2 over the active particles, in chunks of sorted positions (share ``first`` of
    ``step`` of them: :func:`impactsph.physics.chunked.run_chunked` runs the shares on
    numba's threads); ghosts (``order[p] >= n_active``) only take part as neighbours.
    Compiled with PAIR_FASTMATH and without zero-division checks (branches), so that LLVM
    vectorises the neighbour loop of :func:`particle_rates`."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    far = n >= PREFETCH_ROWS  # rows by number that no longer sit in a core's cache
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        L = np.empty((DIM, DIM))  # scratch: the velocity gradient of one particle
        start = chunk * chunk_size
        stop = min((chunk + 1) * chunk_size, n)
        listed = chunk_listed(offsets, indices, start, stop)
        for p in range(start, stop):
            ahead = particle_ahead(order, p, n_active, far)
            if ahead >= 0:  # the rows read and written by number (a hint: the same bits)
                prefetch_row(S, ahead, 2, False)
                prefetch_row(dS, ahead, 2, True)
                prefetch_row(dv, ahead, 2, True)
                prefetch_row(drho, ahead, 1, True)
                prefetch_row(de, ahead, 1, True)
                prefetch_row(de_visc, ahead, 1, True)
                prefetch_row(pair_count, ahead, 1, True)
            i = order[p]
            if i >= n_active:
                if P.shape[1] > U:
                    for a in range(DIM):
                        P[p, U + a] = 0.0
                continue
            particle_rates(p, i, P, offsets, indices, visc_kind, visc_params, normal_stress, S,
                           material, table, drho, dv, de, de_visc, contact_force, pair_count,
                           dS, L, L_sorted, listed, starts, SKIN_FILTER)


@JIT(parallel=PARALLEL_OPTION, cache=True, error_model=BODY_ERROR_MODEL)
def correction_pass(n_active, order, P, offsets, ends, indices, visc_kind, correction_params,
                    correction_books, dv, de, chunk_size):
    """Pass 3 (a scheme with a correction only) over the active particles, each row's
    ``indices[offsets[p]:ends[p]]`` (the inner list's rows: ``NeighbourList.within``)."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    far = n >= PREFETCH_ROWS
    for chunk in nb.prange(n_chunks):
        for p in range(chunk * chunk_size, min((chunk + 1) * chunk_size, n)):
            # the start of the row ahead: its inner entries (neighbours.py)
            prefetch_row(indices, offsets[min(p + PREFETCH_AHEAD, n - 1)], 2, False)
            ahead = particle_ahead(order, p, n_active, far)
            if ahead >= 0:  # (as in pair_pass)
                prefetch_row(correction_books, ahead, 1, True)
                prefetch_row(dv, ahead, 2, True)
                prefetch_row(de, ahead, 1, True)
            i = order[p]
            if i < n_active:
                viscosity_correction(visc_kind, p, i, P, offsets[p], ends[p], indices,
                                     CORRECTION_COLUMNS, DIM, correction_params,
                                     correction_books, dv, de)


# (a prange loop until 2026-12-05, threaded in the serial modules too: compiled serial, the
# vectorised switches' sums had come out in another order than the threaded pass's, which was
# the copy numba's cache holds, not the one a compiling process runs: impactsph.physics.chunked)
@JIT(parallel=CHUNKED_OPTION, cache=True, nogil=True, **NOALIAS,
     fastmath=SWITCH_FASTMATH, error_model=SWITCH_ERROR_MODEL)
def switch_pass(first, step, n_active, order, P, offsets, ends, indices, visc_kind,
                switch_params, elapsed, factor, memory, chunk_size):
    """The viscosity switch (a scheme with one) over the active particles, after the pair
    pass: ``factor[i]``, the particle's factor for the next rate evaluation (``elapsed``: the
    time since the factors in the records were set), each row's ``indices[offsets[p]:
    ends[p]]`` (as in ``correction_pass``)."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        for p in range(chunk * chunk_size, min((chunk + 1) * chunk_size, n)):
            # the start of the row ahead (as in correction_pass)
            prefetch_row(indices, offsets[min(p + PREFETCH_AHEAD, n - 1)], 2, False)
            i = order[p]
            if i < n_active:
                factor[i] = viscosity_switch(visc_kind, p, i, P, offsets[p], ends[p],
                                             indices, SWITCH_COLUMNS, DIM, switch_params,
                                             elapsed, memory)


@JIT(parallel=PARALLEL_OPTION, cache=True, error_model=BODY_ERROR_MODEL)
def friction_pass(n_active, order, P, offsets, indices, visc_kind, visc_params, mu, real_bodies,
                  normal_stress, dv, de, contact_force, chunk_size):
    """Friction between bodies (a case with ``[contact] friction > 0`` only) over the active
    particles, after the pair pass."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    for chunk in nb.prange(n_chunks):
        for p in range(chunk * chunk_size, min((chunk + 1) * chunk_size, n)):
            i = order[p]
            if i < n_active:
                friction_particle(p, i, P, offsets, indices, visc_kind, visc_params, mu,
                                  real_bodies, normal_stress, dv, de, contact_force)


@JIT(parallel=CHUNKED_OPTION, cache=True, nogil=True, **NOALIAS,
     fastmath=PAIR_FASTMATH, error_model="numpy")
def hourglass_pass(first, step, n_active, order, P, L_sorted, offsets, indices, starts,
                   material, table, zeta, hg, dv, de, dhg, chunk_size):
    """The hourglass control over the active particles (after the pair pass, whose velocity
    gradients it reads).  Compiled as :func:`pair_pass`, so that the neighbour loop of
    :func:`hourglass_particle` vectorises (one thread at 1e5 particles: 2D 40.6 -> 20.9 ms,
    3D 163 -> 94 ms; benchmarks/README.md).  The AC correction pass is not: most of its
    neighbour list lies beyond the correction kernel's reach (``2 h_c = h``), which the scalar
    loop skips after the distance, and the masked loop was slower (2D 14.0 -> 16.5 ms, 3D
    35 -> 56 ms)."""
    n = order.shape[0]
    n_chunks = (n + chunk_size - 1) // chunk_size
    far = n >= PREFETCH_ROWS
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        start = chunk * chunk_size
        stop = min((chunk + 1) * chunk_size, n)
        listed = chunk_listed(offsets, indices, start, stop)
        for p in range(start, stop):
            ahead = particle_ahead(order, p, n_active, far)
            if ahead >= 0:  # (as in pair_pass)
                prefetch_row(hg, ahead, 2, False)
                prefetch_row(dhg, ahead, 2, True)
                prefetch_row(dv, ahead, 2, True)
                prefetch_row(de, ahead, 1, True)
            i = order[p]
            if i < n_active:
                hourglass_particle(p, i, P, L_sorted, offsets, indices, material, table, zeta,
                                   hg, dv, de, dhg, listed, starts, SKIN_FILTER)


@JIT(inline="always", cache=True)
def keep_particle(i, x, v, rho, e, S, plastic_work, state, hg, x0, v0, rho0, e0, S0, pw0,
                  state0, hg0):
    """Particle ``i``'s integrated fields into the step's start copy (the deviator as its six
    components, :data:`UPPER`).  Over ``DIM``, a constant, not ``x.shape[1]``: the Taylor
    bar's and the cantilever's predictor stage 0.98 of its time (``bench_pass_ab.py --passes
    stage``, one and two threads, the same bits)."""
    for a in range(DIM):
        x0[i, a] = x[i, a]
        v0[i, a] = v[i, a]
    rho0[i] = rho[i]
    e0[i] = e[i]
    store_upper(S, S0, i)
    pw0[i] = plastic_work[i]
    for c in range(state0.shape[1]):  # (the kept columns: those a model changes)
        state0[i, c] = state[i, c]
    for a in range(hg.shape[1]):
        hg0[i, a] = hg[i, a]


# (a prange loop until 2026-12-06: numba typed and compiled its body twice, the function and then
# the loop's body as a function of its own, 10-12 s on a cold cache; chunked, 6-7 s; and since
# without numba's parallel passes' simplifications, CHUNKED_OPTION, which the pair pass needs
# but the stage hardly: the Taylor bar's stage compiled in 4.0-4.1 s against 5.7-6.3 s, and
# ran 3-5% longer on one thread, about 0.3% of a step: benchmarks/README.md, "A cold first
# command again")
@JIT(cache=True, nogil=True, error_model="numpy")
def stage(first, step, n_active, dt, keep, x0, v0, rho0, e0, S0, pw0, state0, hg0, v_rate, dv,
          drho, de, dS, dhg, clamped, material, table, h, x, v, rho, e, S, plastic_work, state,
          hg, points, normals, inertia, walls, survey, m, hourglass, surveyed, bad_of):
    """One integrator stage of the active particles of share ``first`` of ``step``
    (:mod:`impactsph.physics.chunked`: :func:`impactsph.integrate.run_stage` runs the shares
    and then folds the chunks' results), chunk by chunk of :data:`SURVEY_CHUNK` particles; for
    each particle in turn:

    1. with ``keep``, its integrated fields (``x, v, ...``) into the step's start copy
       (``x0, v0, ...``), before the stage reads that copy (the midpoint step's predictor);
    2. :func:`advance_particle`;
    3. the walls' constraint (:func:`impactsph.boundaries.enforce_particle`, planes
       ``points``, ``normals``; none if they have no rows), its impulse (of the masses
       ``inertia``) and the times it moved the particle into ``walls[chunk] = (moved,
       impulse)``, which :func:`impactsph.physics.survey.fold_stage` adds in chunk order
       into the last row;
    4. with ``survey``, the particle into its chunk's survey
       (:func:`impactsph.physics.survey.survey_particle`, its material density
       ``rho / thickness ratio`` as :attr:`impactsph.state.ParticleState.material_density`;
       masses ``m``, the masses with the added masses ``inertia``, hourglass control's
       ``hourglass``, a particle left behind one of the planes after the constraint a bad
       value): ``surveyed[chunk]``, ``bad_of[chunk]``, which ``fold_stage`` folds into their
       last rows as the survey's own pass folds them
       (:func:`impactsph.physics.survey.fold_survey`), to the same bits.

    Each particle's steps read and write only its own rows, so one pass gives what the
    stage, the walls' pass and the survey gave one after another.  The "numpy" error model
    is the one numba gave the body of the ``prange`` loop this was (the same code); not
    ``NOALIAS``: ``v_rate`` may be ``v``."""
    n_chunks = survey_chunks(n_active)
    for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
        impulse = walls[chunk, 1:]
        for a in range(impulse.shape[0]):
            impulse[a] = 0.0
        moved = 0
        acc = SURVEY_START
        lo, hi = chunk * SURVEY_CHUNK, min((chunk + 1) * SURVEY_CHUNK, n_active)
        for i in range(lo, hi):
            if keep:
                keep_particle(i, x, v, rho, e, S, plastic_work, state, hg, x0, v0, rho0, e0,
                              S0, pw0, state0, hg0)
            advance_particle(i, dt, x0, v0, rho0, e0, S0, pw0, state0, hg0, v_rate, dv, drho,
                             de, dS, dhg, clamped, material, table, h, x, v, rho, e, S,
                             plastic_work, state, hg, not keep)
            if points.shape[0] > 0:
                moved += enforce_particle(i, x, v, inertia, points, normals, impulse)
        walls[chunk, 0] = moved
        if survey:  # the chunk's rows, still in the cache, checked in one vectorised loop
            checked = rows_finite(lo, hi, x, v, rho, e, S)
            for i in range(lo, hi):
                acc = survey_particle(i, n_active, x, v, rho[i] / state[i, THICKNESS_RATIO],
                                      rho, e, S, m, inertia[i], h, material, table,
                                      hourglass, points, normals, acc, checked)
            store_survey(acc, surveyed, bad_of, chunk)


@JIT(parallel=PARALLEL_OPTION, cache=True, error_model=BODY_ERROR_MODEL)
def pressures(rho, e, material, table, out):
    """``out[i]``: the pressure of particle ``i`` from its material's EOS (Pa)."""
    for i in nb.prange(rho.shape[0]):
        out[i] = material_pressure(table, material[i], rho[i], e[i])
    return out


# -- the CUDA kernels ------------------------------------------------------------------------


def cuda_kernels(max_registers=0):
    """The same bodies as CUDA kernels, one thread per sorted position ``p``:
    ``(particle_kernel, pair_kernel, correction_kernel, hourglass_kernel, moment_kernel,
    friction_kernel, switch_kernel, gradient_kernel)``.
    They launch and
    state no physics; :class:`impactsph.gpu.GpuRates` moves the data.
    ``max_registers``: a cap on the pair kernel's registers a thread (0: the compiler's
    choice; ignored by the simulator), for more threads a multiprocessor at the cost of spills
    (``benchmarks/gpu_registers.py``)."""
    global cuda  # a module global, as numba's CUDA simulator expects to find it
    from numba import cuda

    pair_jit = cuda.jit(max_registers=max_registers) if max_registers else cuda.jit

    @cuda.jit
    def particle_kernel(n_rows, order, x, v, m, rho, e, S, carried, h, body, material, table,
                        P):
        p = cuda.grid(1)
        if p < n_rows:
            particle_record(p, order[p], x, v, m, rho, e, S, carried, h, body, material, table,
                            P)

    @pair_jit
    def pair_kernel(n_rows, n_active, order, P, offsets, indices, visc_kind, visc_params,
                    normal_stress, S, material, table, drho, dv, de, de_visc, contact_force,
                    pair_count, dS, L_sorted):
        p = cuda.grid(1)
        if p >= n_rows:
            return
        i = order[p]
        if i >= n_active:  # a ghost: only a neighbour
            if P.shape[1] > U:  # the rows carry u (a correction or a switch reads it)
                for a in range(DIM):
                    P[p, U + a] = 0.0
            return
        L = cuda.local.array((DIM, DIM), nb.float64)
        particle_rates(p, i, P, offsets, indices, visc_kind, visc_params, normal_stress, S,
                       material, table, drho, dv, de, de_visc, contact_force, pair_count, dS, L,
                       L_sorted, indices, offsets, False)

    @cuda.jit
    def correction_kernel(n_rows, n_active, order, P, offsets, indices, visc_kind,
                          correction_params, correction_books, dv, de):
        p = cuda.grid(1)
        if p < n_rows and order[p] < n_active:
            viscosity_correction(visc_kind, p, order[p], P, offsets[p], offsets[p + 1],
                                 indices, CORRECTION_COLUMNS, DIM, correction_params,
                                 correction_books, dv, de)

    @cuda.jit
    def switch_kernel(n_rows, n_active, order, P, offsets, indices, visc_kind, switch_params,
                      elapsed, factor, memory):
        p = cuda.grid(1)
        if p < n_rows and order[p] < n_active:
            factor[order[p]] = viscosity_switch(visc_kind, p, order[p], P, offsets[p],
                                                offsets[p + 1], indices, SWITCH_COLUMNS, DIM,
                                                switch_params, elapsed, memory)

    @cuda.jit
    def moment_kernel(n_rows, P, offsets, indices):
        p = cuda.grid(1)
        if p < n_rows:
            moment_correction(p, P, offsets, indices, indices, offsets, False)

    @cuda.jit
    def gradient_kernel(n_rows, P, offsets, indices):
        p = cuda.grid(1)
        if p < n_rows:
            velocity_gradient_record(p, P, offsets, indices, indices, offsets, False)

    @cuda.jit
    def hourglass_kernel(n_rows, n_active, order, P, L_sorted, offsets, indices, material,
                         table, zeta, hg, dv, de, dhg):
        p = cuda.grid(1)
        if p < n_rows and order[p] < n_active:
            hourglass_particle(p, order[p], P, L_sorted, offsets, indices, material, table,
                               zeta, hg, dv, de, dhg, indices, offsets, False)

    @cuda.jit
    def friction_kernel(n_rows, n_active, order, P, offsets, indices, visc_kind, visc_params,
                        mu, real_bodies, normal_stress, dv, de, contact_force):
        p = cuda.grid(1)
        if p < n_rows and order[p] < n_active:
            friction_particle(p, order[p], P, offsets, indices, visc_kind, visc_params, mu,
                              real_bodies, normal_stress, dv, de, contact_force)

    return (particle_kernel, pair_kernel, correction_kernel, hourglass_kernel, moment_kernel,
            friction_kernel, switch_kernel, gradient_kernel)
