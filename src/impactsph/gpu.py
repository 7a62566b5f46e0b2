"""The rate passes on an NVIDIA GPU (numba-cuda): :class:`GpuRates`, the backend beside
:class:`~impactsph.physics.rates.CpuRates`, with the same ``evaluate`` and the same results to
round-off (docs/gpu.md).

One CUDA thread per particle, gathering over its CSR neighbours like the CPU loop: no atomics,
so each sum runs in the order of the neighbour list and the result does not depend on
scheduling.  The kernels call the same ``@numba.njit`` term functions as the CPU passes
(:mod:`impactsph.physics`, :mod:`impactsph.kernels`): numba-cuda compiles a CPU-jitted
function called from a kernel as a device function, so the physics is written once.  Three
kernels per evaluation, over the list's sorted positions ``p`` (particle ``order[p]``; the
identity for a list without an order), so that threads of a warp work on neighbouring
particles and read neighbouring memory:

1. every row, ghosts included: the copies of what the pair loop reads
   (``x, v, h, m, rho, c, P/rho^2, V = m/rho``, body, ``A = sigma/rho^2``) in sorted order;
2. every active particle: the neighbour sums of eqs 22, 27, 28 (continuity, stress and
   viscous accelerations, stress work, viscous heating, velocity gradient, contact terms,
   pair count), then the Jaumann stress rate (eq 14) from the velocity gradient just summed;
3. with the acceleration correction only, every active particle: ``-u_corr`` and its energy
   term (eqs 33-37).

The neighbour list, the ghosts and the time integration stay on the CPU.  Device arrays are
kept between calls: the neighbour list is uploaded when the solver hands over a new one, the
constant per-particle fields (``m, h, material, body``) and the material table when it hands
over other arrays (new ghosts, a restart), the evolving fields (``x, v, rho, e, S``) on every
call; the results are copied back into the host
:class:`~impactsph.physics.rates.RateBuffers`.

Under numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``, set before numba is imported) the
same kernels run on the CPU, interpreted: that is how the tests check them on machines without
a GPU (``tests/test_gpu.py``).  The simulator's arrays cannot be passed to compiled functions,
so there the kernels call the term functions' Python source (``.py_func``): the same code.
"""

from __future__ import annotations

import importlib.util
import math
from functools import cache

import numba as nb
import numpy as np

from .kernels import cubic_spline_dwdr_q
from .materials import SHEAR, WAVE_MODULUS
from .physics.contact import contact_acceleration_pair, contact_work_pair, in_contact
from .physics.continuity import continuity_pair, velocity_gradient_pair
from .physics.correction import (
    corrected_viscous_acceleration,
    correction_energy_rate,
    correction_weight,
)
from .physics.energy import stress_work_pair, viscous_heating_pair
from .physics.momentum import stress_acceleration_pair, viscous_acceleration_pair
from .physics.rates import material_pressure
from .physics.stress_rate import jaumann_stress_rate
from .physics.viscosity import monaghan_viscosity

try:  # numba-cuda (the `gpu` extra) when installed, else numba's deprecated built-in target
    from numba import cuda

    _IMPORT_ERROR = None
except Exception as exc:  # noqa: BLE001 - pragma: no cover - a numba without a CUDA target
    cuda = None
    _IMPORT_ERROR = f"{type(exc).__name__}: {exc}"

#: Threads per block on a GPU, and under the simulator (which starts one Python thread per
#: CUDA thread of the grid: smaller blocks start fewer idle ones).
THREADS_PER_BLOCK = 128
SIMULATOR_THREADS_PER_BLOCK = 32

INSTALL_HINT = "pip install 'impactsph[gpu]'"


def simulator_enabled() -> bool:
    """Whether numba's CUDA simulator replaces the GPU in this process
    (``NUMBA_ENABLE_CUDASIM=1`` when numba was imported)."""
    if cuda is None:
        return False
    try:
        from numba.cuda.core import config  # numba-cuda
    except ImportError:
        from numba.core import config  # numba's built-in CUDA target
    return bool(config.ENABLE_CUDASIM)


def unavailable_reason() -> str | None:
    """Why no GPU can be used here, or ``None`` when one can."""
    if simulator_enabled():
        return "numba's CUDA simulator is enabled (NUMBA_ENABLE_CUDASIM=1), not a GPU"
    if importlib.util.find_spec("numba_cuda") is None:
        # numba's own CUDA target is deprecated and needs a CUDA toolkit installed apart
        return f"numba-cuda is not installed ({INSTALL_HINT})"
    if cuda is None:  # pragma: no cover - numba-cuda installed but not importable
        return f"numba.cuda cannot be imported ({_IMPORT_ERROR})"
    try:
        if not cuda.is_available():
            return "no CUDA GPU or driver was found"
    except Exception as exc:  # noqa: BLE001 - any driver error means no GPU
        return f"the CUDA driver failed ({exc})"
    return None


@cache
def gpu_kernels(dim: int, simulated: bool):
    """The CUDA kernels for dimension ``dim`` (a compile-time constant, as on the CPU):
    ``(particle_kernel, pair_kernel, correction_kernel)``.  ``simulated``: build them for
    the CUDA simulator (term functions called through their Python source)."""

    def device(f):
        return f.py_func if simulated else f

    pressure_of = device(material_pressure)
    dwdr_q = device(cubic_spline_dwdr_q)
    continuity = device(continuity_pair)
    grad_v = device(velocity_gradient_pair)
    stress_acc = device(stress_acceleration_pair)
    stress_work = device(stress_work_pair)
    touching = device(in_contact)
    contact_acc = device(contact_acceleration_pair)
    contact_work = device(contact_work_pair)
    viscosity = device(monaghan_viscosity)
    visc_acc = device(viscous_acceleration_pair)
    visc_heat = device(viscous_heating_pair)
    jaumann = device(jaumann_stress_rate)
    weight = device(correction_weight)
    corrected = device(corrected_viscous_acceleration)
    energy_rate = device(correction_energy_rate)

    @cuda.jit
    def particle_kernel(n_rows, order, x, v, m, rho, e, S, h, body, material, table,
                        xs, vs, hs, ms, rhos, cs, pcs, vols, bodies, As):
        """Pass 1 for sorted position ``p``, particle ``i = order[p]``, ghosts included:
        ``c``, ``V = m/rho``, ``P/rho^2``, ``A = (-P I + S)/rho^2`` and copies of what the
        pair loop reads into row ``p`` of the sorted arrays (neighbours close in space are
        close in memory)."""
        p = cuda.grid(1)
        if p >= n_rows:
            return
        i = order[p]
        k = material[i]
        pr = pressure_of(table, k, rho[i], e[i])
        c = math.sqrt(table[k, WAVE_MODULUS] / rho[i])
        inv_rho2 = 1.0 / (rho[i] * rho[i])
        for a in range(dim):
            xs[p, a] = x[i, a]
            vs[p, a] = v[i, a]
            for b in range(dim):
                As[p, a, b] = S[i, a, b] * inv_rho2
            As[p, a, a] -= pr * inv_rho2
        hs[p] = h[i]
        ms[p] = m[i]
        rhos[p] = rho[i]
        cs[p] = c
        pcs[p] = pr * inv_rho2
        vols[p] = m[i] / rho[i]
        bodies[p] = body[i]

    @cuda.jit
    def pair_kernel(n_rows, n_active, order, xs, vs, hs, ms, rhos, cs, pcs, vols, bodies, As,
                    offsets, indices, alpha1, alpha2, epsilon, S, material, table,
                    drho, dv, de, de_visc, contact_force, pair_count, dS, u_sorted):
        """Pass 2 for the active particle ``i = order[p]``: the neighbour sums (eqs 22, 27,
        28; the term functions pair by pair, summed in the order of the list in thread-local
        arrays), then its Jaumann rate (eq 14).  Writes the totals ``dv``, ``de`` and the
        viscous heating; the viscous acceleration is kept in sorted order (``u_sorted``) for
        the correction kernel."""
        p = cuda.grid(1)
        if p >= n_rows:
            return
        i = order[p]
        if i >= n_active:  # a ghost: only a neighbour
            for a in range(dim):
                u_sorted[p, a] = 0.0
            return
        gradw = cuda.local.array(dim, nb.float64)
        v_ij = cuda.local.array(dim, nb.float64)
        r_ij = cuda.local.array(dim, nb.float64)
        acc_s = cuda.local.array(dim, nb.float64)
        acc_v = cuda.local.array(dim, nb.float64)
        force = cuda.local.array(dim, nb.float64)
        L_i = cuda.local.array((dim, dim), nb.float64)
        A_i = As[p]
        m_i = ms[p]
        rho_i = rhos[p]
        drho_i = 0.0
        de_s = 0.0
        de_v = 0.0
        for a in range(dim):
            acc_s[a] = 0.0
            acc_v[a] = 0.0
            force[a] = 0.0
            for b in range(dim):
                L_i[a, b] = 0.0
        count = 0
        for k in range(offsets[p], offsets[p + 1]):
            q = indices[k]
            r2 = 0.0
            for a in range(dim):
                r_ij[a] = xs[p, a] - xs[q, a]
                r2 += r_ij[a] * r_ij[a]
            h_ij = 0.5 * (hs[p] + hs[q])
            inv_h = 1.0 / h_ij
            q2 = r2 * inv_h * inv_h
            if q2 >= 4.0 or r2 == 0.0:
                continue
            count += 1
            r = math.sqrt(r2)
            f = dwdr_q(r * inv_h, inv_h, dim) / r
            vg = 0.0
            vr = 0.0
            for a in range(dim):
                gradw[a] = f * r_ij[a]
                v_ij[a] = vs[p, a] - vs[q, a]
                vg += v_ij[a] * gradw[a]
                vr += v_ij[a] * r_ij[a]
            m_j = ms[q]
            volume_j = vols[q]
            same_body = bodies[p] == bodies[q]
            if same_body:
                drho_i += continuity(rho_i, volume_j, vg)
                A_j = As[q]
                for a in range(dim):
                    acc_s[a] += stress_acc(m_j, A_i, A_j, gradw, a, dim)
                    for b in range(dim):
                        L_i[a, b] += grad_v(volume_j, v_ij[a], gradw[b])
                de_s += stress_work(m_j, A_i, v_ij, gradw, dim)
            else:  # another body or a wall ghost: compression-only contact
                s_ij = pcs[p] + pcs[q]
                if touching(s_ij, vg):
                    drho_i += continuity(rho_i, volume_j, vg)
                    for a in range(dim):
                        fa = contact_acc(m_j, s_ij, gradw[a])
                        acc_s[a] += fa
                        force[a] += m_i * fa
                    de_s += contact_work(m_j, pcs[p], s_ij, vg)
            pi_ij = viscosity(vr, r2, h_ij, 0.5 * (cs[p] + cs[q]), 0.5 * (rho_i + rhos[q]),
                              alpha1, alpha2, epsilon)
            if pi_ij != 0.0:
                for a in range(dim):
                    fa = visc_acc(m_j, pi_ij, gradw[a])
                    acc_v[a] += fa
                    if not same_body:
                        force[a] += m_i * fa
                de_v += visc_heat(m_j, pi_ij, vg)
        for a in range(dim):
            dv[i, a] = acc_s[a] + acc_v[a]
            u_sorted[p, a] = acc_v[a]
            contact_force[i, a] = force[a]
        drho[i] = drho_i
        de_visc[i] = de_v
        de[i] = de_s + de_v
        pair_count[i] = count
        jaumann(L_i, S[i], table[material[i], SHEAR], dS[i])

    @cuda.jit
    def correction_kernel(n_rows, n_active, order, xs, vs, hs, ms, rhos, bodies, offsets,
                          indices, u_sorted, h_ratio, variant, energy_mode, dv_corr, de_corr,
                          dv, de):
        """Pass 4 (AC only) for the active particle ``i = order[p]``: ``-u_corr_i`` and its
        energy term, from the viscous accelerations of pass 2 in sorted order, also added to
        the totals ``dv``, ``de``."""
        p = cuda.grid(1)
        if p >= n_rows:
            return
        i = order[p]
        if i >= n_active:
            return
        weighted_u = cuda.local.array(dim, nb.float64)
        for a in range(dim):
            weighted_u[a] = 0.0
        weight_sum = 0.0
        paper_energy = 0.0
        self_weight = weight(ms[p] / rhos[p], 0.0, h_ratio * hs[p], dim)
        for k in range(offsets[p], offsets[p + 1]):
            q = indices[k]
            if bodies[q] != bodies[p]:
                continue
            h_c = h_ratio * 0.5 * (hs[p] + hs[q])
            r2 = 0.0
            for a in range(dim):
                d = xs[p, a] - xs[q, a]
                r2 += d * d
            if r2 >= 4.0 * h_c * h_c:
                continue
            w = weight(ms[q] / rhos[q], math.sqrt(r2), h_c, dim)
            weight_sum += w
            for a in range(dim):
                weighted_u[a] += w * u_sorted[q, a]
                paper_energy += 0.5 * w * (vs[p, a] - vs[q, a]) * u_sorted[q, a]
        work = 0.0
        for a in range(dim):
            u_i = u_sorted[p, a]
            net = corrected(u_i, self_weight, weight_sum, weighted_u[a], variant)
            dv_corr[i, a] = net - u_i
            work -= vs[p, a] * (net - u_i)
        de_corr[i] = energy_rate(work, paper_energy, weight_sum, self_weight, variant,
                                 energy_mode)
        for a in range(dim):
            dv[i, a] += dv_corr[i, a]
        de[i] += de_corr[i]

    return particle_kernel, pair_kernel, correction_kernel


#: The kernels' outputs for the active rows, copied into the ``RateBuffers`` of that name
#: (a buffer without rows, e.g. no contact or no AC, is skipped).
_ACTIVE_OUT = ("drho", "dv", "de", "de_visc", "contact_force", "pair_count", "dS")
_CORRECTION_OUT = ("dv_corr", "de_corr")


class GpuRates:
    """The rate passes on an NVIDIA GPU: fills a :class:`RateBuffers` as
    :class:`~impactsph.physics.rates.CpuRates` does, to round-off.  Under the CUDA
    simulator the same kernels run on the CPU, slowly (for tests).
    """

    device = "gpu"

    def __init__(self, dim: int, *, threads_per_block: int | None = None):
        if cuda is None:  # pragma: no cover - a numba without any CUDA target
            raise RuntimeError(f"numba.cuda cannot be imported ({_IMPORT_ERROR}; "
                               f"{INSTALL_HINT})")
        self.dim = dim
        simulated = simulator_enabled()
        self.threads_per_block = threads_per_block or (
            SIMULATOR_THREADS_PER_BLOCK if simulated else THREADS_PER_BLOCK)
        self._kernels = gpu_kernels(dim, simulated)
        self._stream = cuda.stream()
        self._device: dict[str, object] = {}  # name -> device array, reused while it fits
        self._uploaded: dict[str, np.ndarray] = {}  # name -> host array last uploaded
        self.uploads = 0  # host-to-device copies so far (for tests and tuning)

    # -- device memory ---------------------------------------------------------------------
    def _buffer(self, name: str, shape: tuple, dtype) -> object:
        """The device array ``name``, (re)allocated when its shape or type changes."""
        d = self._device.get(name)
        if d is None or d.shape != tuple(shape) or d.dtype != np.dtype(dtype):
            d = cuda.device_array(shape, dtype=dtype, stream=self._stream)
            self._device[name] = d
        return d

    def _upload(self, name: str, host: np.ndarray, keep: bool = False) -> object:
        """Copy ``host`` to the device array ``name``.  ``keep``: skip the copy when ``host``
        is the very array uploaded last time (the solver hands over new arrays when these
        fields change: a new neighbour list, new ghosts, a restart)."""
        if keep and self._uploaded.get(name) is host:
            return self._device[name]
        d = self._buffer(name, host.shape, host.dtype)
        if host.size:
            d.copy_to_device(np.ascontiguousarray(host), stream=self._stream)
            self.uploads += 1
        if keep:
            self._uploaded[name] = host
        return d

    def _download(self, name: str, host: np.ndarray, rows: int) -> None:
        """Rows ``:rows`` of the device array ``name`` into ``host`` (a buffer the solver
        does not need may have no rows: then nothing is copied)."""
        rows = min(rows, host.shape[0])
        if rows:
            self._device[name][:rows].copy_to_host(host[:rows], stream=self._stream)

    # -- the backend interface ---------------------------------------------------------------
    def evaluate(self, n_active: int, arrays: tuple, table: np.ndarray, neighbours,
                 alpha1: float, alpha2: float, epsilon: float, correction: tuple | None,
                 b) -> None:
        """As :meth:`impactsph.physics.rates.CpuRates.evaluate`: the rates of the first
        ``n_active`` rows of ``arrays = (x, v, rho, e, S, m, h, material, body)`` into the
        host buffers ``b``; rows the CPU backend leaves alone are left alone."""
        x, v, rho, e, S, m, h, material, body = arrays
        particle_kernel, pair_kernel, correction_kernel = self._kernels
        n_rows, dim = rho.shape[0], self.dim
        stream, tpb = self._stream, self.threads_per_block
        up = self._upload
        # the state (every call); the constant fields and the list (when they are new arrays)
        dx, dv, drho_, de, dS_ = (up("x", x), up("v", v), up("rho", rho), up("e", e),
                                  up("S", S))
        dm, dh, dmat, dbody = (up("m", m, True), up("h", h, True),
                               up("material", material, True), up("body", body, True))
        dtable = up("table", table, True)
        order = neighbours.order
        dorder = up("order", order, True)
        doff = up("offsets", neighbours.offsets, True)
        dind = up("indices", neighbours.indices, True)
        # sorted copies and outputs, allocated once per size
        buf = self._buffer
        xs, vs, As = (buf("xs", (n_rows, dim), np.float64), buf("vs", (n_rows, dim), np.float64),
                      buf("As", (n_rows, dim, dim), np.float64))
        hs, ms, rhos, cs, pcs, vols = (buf(k, (n_rows,), np.float64) for k in (
            "hs", "ms", "rhos", "cs", "pcs", "vols"))
        bodies = buf("bodies", (n_rows,), body.dtype)
        u_sorted = buf("u_sorted", (n_rows, dim), np.float64)
        shapes = {"drho": (n_rows,), "de": (n_rows,), "de_visc": (n_rows,),
                  "de_corr": (n_rows,), "pair_count": (n_rows,), "dS": (n_rows, 3, 3)}
        count_type = getattr(b.pair_count, "dtype", np.int64)
        out = {name: buf("out_" + name, shapes.get(name, (n_rows, dim)),
                         count_type if name == "pair_count" else np.float64)
               for name in (*_ACTIVE_OUT, *_CORRECTION_OUT)}
        if n_rows:
            blocks = (n_rows + tpb - 1) // tpb
            particle_kernel[blocks, tpb, stream](
                n_rows, dorder, dx, dv, dm, drho_, de, dS_, dh, dbody, dmat, dtable,
                xs, vs, hs, ms, rhos, cs, pcs, vols, bodies, As)
            if n_active:
                pair_kernel[blocks, tpb, stream](
                    n_rows, n_active, dorder, xs, vs, hs, ms, rhos, cs, pcs, vols, bodies, As,
                    doff, dind, float(alpha1), float(alpha2), float(epsilon), dS_, dmat,
                    dtable, out["drho"], out["dv"], out["de"], out["de_visc"],
                    out["contact_force"], out["pair_count"], out["dS"], u_sorted)
                if correction is not None:
                    h_ratio, variant, energy_mode = correction
                    correction_kernel[blocks, tpb, stream](
                        n_rows, n_active, dorder, xs, vs, hs, ms, rhos, bodies, doff, dind,
                        u_sorted, float(h_ratio), int(variant), int(energy_mode),
                        out["dv_corr"], out["de_corr"], out["dv"], out["de"])
        # results into the host buffers
        for names in (_ACTIVE_OUT, _CORRECTION_OUT if correction is not None else ()):
            for name in names:
                if hasattr(b, name):
                    self._download("out_" + name, getattr(b, name), n_active)
        stream.synchronize()
