"""The rate passes on an NVIDIA GPU (numba-cuda): :class:`GpuRates`, the backend beside
:class:`~impactsph.physics.rates.CpuRates`, with the same ``evaluate`` and the same results to
round-off (docs/gpu.md).

This module launches and moves data; it states no physics.  The kernels are those of
:func:`impactsph.physics.passes.cuda_kernels`: the very bodies the CPU passes run
(``particle_record``, ``particle_rates``, the scheme's correction), bound to the registered
models by :mod:`impactsph.codegen`, one CUDA thread per sorted position ``p`` (particle
``order[p]``), gathering over its CSR neighbours like the CPU loop: no atomics, so each sum runs
in the order of the neighbour list and the result does not depend on scheduling.  The packed
particle records (:mod:`impactsph.physics.records`) are built on the device and read there,
stored by column (:data:`RECORD_ORDER`).

The neighbour list, the ghosts and the time integration stay on the CPU.  Device arrays are
kept between calls: the neighbour list is uploaded when the solver hands over a new one, the
constant per-particle fields (``m, h, material, body``) and the material table when it hands
over other arrays (new ghosts, a restart), the evolving fields (``x, v, rho, e, S``) on every
call; the results are copied back into the host
:class:`~impactsph.physics.rates.RateBuffers`.

Under numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``, set before numba is imported) the
same kernels run on the CPU, interpreted: that is how the tests check them on machines without
a GPU (``tests/test_gpu.py``).  The simulator's arrays cannot be passed to compiled functions,
so there the generated module is built with its bodies as plain Python (the same source).
"""

from __future__ import annotations

import importlib.util
import os
from functools import cache

import numpy as np

from .jitcache import copy_sets_of_names_shallowly, inline_fresh_ir_in_place
from .physics.options import PassOptions
from .physics.rates import compiled_passes

try:  # numba-cuda (the `gpu` extra) when installed, else numba's deprecated built-in target
    from numba import cuda

    _IMPORT_ERROR = None
except Exception as exc:  # noqa: BLE001 - pragma: no cover - a numba without a CUDA target
    cuda = None
    _IMPORT_ERROR = f"{type(exc).__name__}: {exc}"
else:  # numba-cuda's copies of numba's inliner and IR utilities, changed too (jitcache)
    try:
        from numba.cuda.core import inline_closurecall as _cuda_inliner
        from numba.cuda.core import ir_utils as _cuda_ir_utils
    except ImportError:  # numba's built-in target: numba's own modules, already changed
        pass
    else:
        inline_fresh_ir_in_place(_cuda_inliner)
        copy_sets_of_names_shallowly(_cuda_ir_utils)

#: Threads per block on a GPU, and under the simulator (which starts one Python thread per
#: CUDA thread of the grid: smaller blocks start fewer idle ones).  8 rather than 32 since
#: 2026-12-05: the test worker's whole-step runs took 53 s against 62 s, its 100-step runs 28 s
#: against 38 s (alternated, one process each), and the small cases then span several blocks,
#: so the kernels' sums across blocks are exercised too.
THREADS_PER_BLOCK = 128
SIMULATOR_THREADS_PER_BLOCK = 8

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
    try:
        # the kernels' typing, which numba-cuda loads at the first compilation: numba-cuda
        # 0.30 registers np.row_stack there, which numpy 2.5 removed, and is in maintenance
        # (NVIDIA/numba-cuda#907), so with numpy 2.5 no kernel compiles (seen on an H200)
        importlib.import_module("numba.cuda.np.npyimpl")
    except Exception as exc:  # noqa: BLE001 - any failure here means no kernel compiles
        return (f"numba-cuda cannot compile kernels with numpy {np.__version__} "
                f"({type(exc).__name__}: {exc}); pip install 'numpy<2.5'")
    return None


@cache
def gpu_kernels(dim: int, simulated: bool, version: int = 0,
                options: PassOptions | str | None = None, max_registers: int = 0):
    """The CUDA kernels for dimension ``dim`` and the registered models (``version``: the
    registries' version, so that a newly registered model gets new kernels):
    the eight kernels of :func:`impactsph.physics.passes.cuda_kernels`, whether the forces
    are corrected, whether the viscosity reconstructs the velocity and the record's columns
    (unpadded: the records are stored by column, :data:`RECORD_ORDER`).
    ``simulated``: built for the CUDA simulator. ``max_registers``: the pair kernel's cap
    (:func:`launch_settings`)."""
    passes = compiled_passes(dim, simulated, PassOptions.coerce(options))
    return (*passes.cuda_kernels(0 if simulated else max_registers), passes.FORCE_CORRECTION,
            passes.VELOCITY_RECONSTRUCTION, passes.RECORD_COLUMNS)


def record_columns(columns: int, dim: int, viscosity) -> int:
    """The device records' columns for ``viscosity``: all ``columns``, less the viscous
    acceleration's (the last ``dim``) for a scheme with neither a correction nor a switch,
    which no pass reads then (as :meth:`impactsph.physics.rates.CpuRates.record_columns`)."""
    needed = viscosity.correction is not None or viscosity.switch is not None
    return columns if needed else columns - dim


#: The packed records' layout on the device: Fortran order, each column (a field of every
#: particle) contiguous.  The bodies index ``P[p, column]`` as on the CPU, whose records are
#: rows; on the GPU a warp's 32 threads then read one field of 32 neighbours (in the list's
#: cell order, mostly consecutive rows) from one or two 128-byte lines, where rows spread
#: them over 32 lines.  3D, 1M particles, H200: the pair kernel 4.2 ms an evaluation with
#: rows, at 86% of its L1 throughput (ncu), 18% occupancy (benchmarks/README.md).
RECORD_ORDER = "F"


def out_of_memory(exc: BaseException) -> bool:
    """Whether ``exc`` is the CUDA driver's refusal of an allocation
    (``CUDA_ERROR_OUT_OF_MEMORY``, code 2, raised by numba-cuda after it has freed what it
    had deferred and tried again)."""
    if "CUDA_ERROR_OUT_OF_MEMORY" in str(exc):
        return True
    code = getattr(exc, "code", None)
    try:
        return type(exc).__name__ == "CudaAPIError" and int(code) == 2
    except (TypeError, ValueError):
        return False


def free_memory() -> tuple[int | None, str]:
    """``(free bytes, name)`` of the GPU this process uses (its CUDA context made if it has
    none yet: a run then reuses it); ``(None, what)`` under numba's CUDA simulator (whose
    memory is the host's) or where the driver does not say."""
    if simulator_enabled():
        return None, "numba's CUDA simulator: not checked"
    try:
        free, _total = cuda.current_context().get_memory_info()
        name = cuda.get_current_device().name
    except Exception as exc:  # noqa: BLE001 - a driver that cannot say: nothing is checked
        return None, f"GPU memory unknown: {exc}"
    if isinstance(name, bytes):
        name = name.decode(errors="replace")
    return int(free), str(name)


#: the launch settings' environment variables (for tuning on a given GPU, benchmarks/bench_gpu.py)
THREADS_ENV = "IMPACTSPH_CUDA_THREADS_PER_BLOCK"
REGISTERS_ENV = "IMPACTSPH_CUDA_MAX_REGISTERS"


def launch_settings(environ: dict | None = None) -> tuple[int, int]:
    """``(threads_per_block, max_registers)`` from ``$IMPACTSPH_CUDA_THREADS_PER_BLOCK``
    (a power of two from 32 to 512: the step's block sums need a power of two; default 128)
    and ``$IMPACTSPH_CUDA_MAX_REGISTERS`` (the pair kernel's registers a thread, 32-255, or
    0 for the compiler's choice, the default). A bad value is refused with the variable, the
    value and what is allowed, before anything is compiled."""
    environ = os.environ if environ is None else environ
    values = []
    for name, default, allowed, ok in (
            (THREADS_ENV, THREADS_PER_BLOCK, "a power of two from 32 to 512",
             lambda t: 32 <= t <= 512 and not t & (t - 1)),
            (REGISTERS_ENV, 0, "0 (the compiler's choice) or 32 to 255",
             lambda r: r == 0 or 32 <= r <= 255)):
        text = environ.get(name, "").strip()
        try:
            value = int(text) if text else default
        except ValueError:
            value = None
        if value is None or not ok(value):
            raise ValueError(f"{name} = {text!r}: allowed is {allowed}")
        values.append(value)
    return values[0], values[1]


#: The kernels' outputs for the active rows, copied into the ``RateBuffers`` of that name
#: (a buffer without rows, e.g. no contact or no AC, is skipped).
_ACTIVE_OUT = ("drho", "dv", "de", "de_visc", "contact_force", "pair_count", "dS")
_CORRECTION_OUT = ("correction_books",)
_SWITCH_OUT = ("factor", "memory")


class GpuRates:
    """The rate passes on an NVIDIA GPU: fills a :class:`RateBuffers` as
    :class:`~impactsph.physics.rates.CpuRates` does, to round-off.  Under the CUDA
    simulator the same kernels run on the CPU, slowly (for tests).
    """

    device = "gpu"

    def __init__(self, dim: int, options: PassOptions | str | None = None, *,
                 threads_per_block: int | None = None):
        if cuda is None:  # pragma: no cover - a numba without any CUDA target
            raise RuntimeError(f"numba.cuda cannot be imported ({_IMPORT_ERROR}; "
                               f"{INSTALL_HINT})")
        self.dim = dim
        simulated = simulator_enabled()
        threads, self.max_registers = launch_settings()
        self.threads_per_block = threads_per_block or (
            SIMULATOR_THREADS_PER_BLOCK if simulated else threads)
        from .models import registry

        self.options = PassOptions.coerce(options)
        self._kernels = gpu_kernels(dim, simulated, registry.version(), self.options,
                                    self.max_registers)
        #: the passes' module (its record columns: a symmetry plane's mirror reads them)
        self._passes = compiled_passes(dim, simulated, self.options)
        self._stream = cuda.stream()
        self._device: dict[str, object] = {}  # name -> device array, reused while it fits
        self._uploaded: dict[str, np.ndarray] = {}  # name -> host array last uploaded
        self.uploads = 0  # host-to-device copies so far (for tests and tuning)

    # -- device memory ---------------------------------------------------------------------
    def _buffer(self, name: str, shape: tuple, dtype, order: str = "C") -> object:
        """The device array ``name``, (re)allocated when its shape or type changes."""
        d = self._device.get(name)
        if d is None or d.shape != tuple(shape) or d.dtype != np.dtype(dtype):
            d = cuda.device_array(shape, dtype=dtype, order=order, stream=self._stream)
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

    def _on_host(self, callback, packed, gradients, column: int) -> None:
        """``callback(records, [gradients,] column)`` on the host, on copies of the device's
        records (and the velocity gradients, where given) that go back up after it."""
        s = self._stream
        records = packed.copy_to_host(stream=s)
        matrices = (None if gradients is None else gradients.copy_to_host(stream=s)
                    if gradients.size else np.zeros(gradients.shape))
        s.synchronize()
        if matrices is None:
            callback(records, column)
        else:
            callback(records, matrices, column)
        packed.copy_to_device(records, stream=s)
        if matrices is not None and matrices.size:
            gradients.copy_to_device(matrices, stream=s)

    def release(self) -> None:
        """Let go of the device arrays of the host path (the state's copies, the neighbour
        list, the packed records, the outputs). A run whose state went to the device
        (:class:`~impactsph.gpu_step.ResidentStep`, which has arrays of its own) no longer
        reads them: kept, they were 45% of its device memory in 3D (837 of 1,815 B a
        particle at 4,096 particles, counted in the simulator). A later :meth:`evaluate`
        allocates them again."""
        self._device.clear()
        self._uploaded.clear()

    def _download(self, name: str, host: np.ndarray, rows: int) -> None:
        """Rows ``:rows`` of the device array ``name`` into ``host`` (a buffer the solver
        does not need may have no rows: then nothing is copied)."""
        rows = min(rows, host.shape[0])
        if rows:
            self._device[name][:rows].copy_to_host(host[:rows], stream=self._stream)

    # -- the backend interface ---------------------------------------------------------------
    def evaluate(self, n_active: int, arrays: tuple, table: np.ndarray, neighbours,
                 viscosity, b, hourglass: float = 0.0,
                 hourglass_acceleration: np.ndarray | None = None,
                 after_pairs=None, after_moments=None, n_bodies: int = 1,
                 switch_elapsed: float = 0.0, uniform_h: bool | None = None) -> None:
        """As :meth:`impactsph.physics.rates.CpuRates.evaluate`: the rates of the first
        ``n_active`` rows of ``arrays = (x, v, rho, e, S, m, h, material, body, carried)`` into the
        host buffers ``b``; rows the CPU backend leaves alone are left alone.  ``uniform_h``
        is ignored: the device's kernels are those of the run's own options, which read each
        pair's h (the same results).  ``after_pairs`` and ``after_moments`` (a symmetry
        plane's ghosts' mirror, :class:`~impactsph.solver.Solver`'s) run on the host, on the
        records copied down and back up (:meth:`_on_host`): the whole step on the device
        mirrors them there (:mod:`impactsph.gpu_step`)."""
        x, v, rho, e, S, m, h, material, body, carried = arrays
        (particle_kernel, pair_kernel, correction_kernel, hourglass_kernel, moment_kernel,
         friction_kernel, switch_kernel, gradient_kernel, force_correction, reconstruction,
         record_width) = self._kernels
        viscosity.check_compiled(reconstruction, self.options.viscosity_factor)
        n_rows, dim = rho.shape[0], self.dim
        stream, tpb = self._stream, self.threads_per_block
        up = self._upload
        # the state (every call); the constant fields and the list (when they are new arrays)
        dx, dv, drho_, de, dS_ = (up("x", x), up("v", v), up("rho", rho), up("e", e),
                                  up("S", S))
        dcarried = up("carried", carried)
        dm, dh, dmat, dbody = (up("m", m, True), up("h", h, True),
                               up("material", material, True), up("body", body, True))
        dtable = up("table", table, True)
        dorder = up("order", neighbours.order, True)
        doff = up("offsets", neighbours.offsets, True)
        dind = up("indices", neighbours.indices, True)
        # the packed records and the outputs, allocated once per size
        buf = self._buffer
        packed = buf("packed", (n_rows, record_columns(record_width, dim, viscosity)),
                     self.options.record_dtype, RECORD_ORDER)
        shapes = {"drho": (n_rows,), "de": (n_rows,), "de_visc": (n_rows,),
                  "correction_books": (n_rows, 2), "pair_count": (n_rows,), "dS": (n_rows, 6),
                  "factor": (n_rows,), "memory": (n_rows,)}
        count_type = getattr(b.pair_count, "dtype", np.int64)
        corrected = viscosity.correction is not None
        switched = viscosity.switch is not None
        # an output no kernel of this run writes has no rows: the contact force without
        # contact, the correction's without a correction, the switch's without a switch
        unused = {*(() if b.contact_force.shape[0] else ("contact_force",)),
                  *(() if corrected else _CORRECTION_OUT), *(() if switched else _SWITCH_OUT)}
        out = {name: buf("out_" + name, (0 if name in unused else n_rows,
                                         *shapes.get(name, (n_rows, dim))[1:]),
                         count_type if name == "pair_count" else np.float64)
               for name in (*_ACTIVE_OUT, *_CORRECTION_OUT, *_SWITCH_OUT)}
        with_hourglass = hourglass > 0.0
        gradients = buf("gradients", (n_rows if with_hourglass else 0, dim, dim), np.float64)
        out["dhg"] = buf("out_dhg", (n_rows if with_hourglass else 0, dim), np.float64)
        if n_rows:
            blocks = (n_rows + tpb - 1) // tpb
            particle_kernel[blocks, tpb, stream](
                n_rows, dorder, dx, dv, dm, drho_, de, dS_, dcarried, dh, dbody, dmat, dtable,
                packed)
            if force_correction:
                moment_kernel[blocks, tpb, stream](n_rows, packed, doff, dind)
                if after_moments is not None:
                    self._on_host(after_moments, packed, None, self._passes.CM0)
            if reconstruction:
                gradient_kernel[blocks, tpb, stream](n_rows, packed, doff, dind)
                if after_moments is not None:
                    self._on_host(after_moments, packed, None, self._passes.LV0)
            if n_active:
                pair_kernel[blocks, tpb, stream](
                    n_rows, n_active, dorder, packed, doff, dind, int(viscosity.kind),
                    viscosity.pair, self.options.normal_stress, dS_, dmat, dtable,
                    out["drho"], out["dv"], out["de"],
                    out["de_visc"], out["contact_force"], out["pair_count"], out["dS"],
                    gradients)
                if after_pairs is not None:
                    self._on_host(after_pairs, packed, gradients, self._passes.U)
                if self.options.contact_friction > 0.0:
                    friction_kernel[blocks, tpb, stream](
                        n_rows, n_active, dorder, packed, doff, dind, int(viscosity.kind),
                        viscosity.pair, float(self.options.contact_friction), int(n_bodies),
                        self.options.normal_stress, out["dv"], out["de"],
                        out["contact_force"])
                if corrected:
                    correction_kernel[blocks, tpb, stream](
                        n_rows, n_active, dorder, packed, doff, dind, int(viscosity.kind),
                        viscosity.correction, out["correction_books"], out["dv"], out["de"])
                if switched:
                    switch_kernel[blocks, tpb, stream](
                        n_rows, n_active, dorder, packed, doff, dind, int(viscosity.kind),
                        viscosity.switch, float(switch_elapsed), out["factor"],
                        out["memory"])
                if with_hourglass:
                    dhg_state = up("hourglass_acceleration", hourglass_acceleration)
                    hourglass_kernel[blocks, tpb, stream](
                        n_rows, n_active, dorder, packed, gradients, doff, dind, dmat, dtable,
                        float(hourglass), dhg_state, out["dv"], out["de"], out["dhg"])
        # results into the host buffers
        for names in (_ACTIVE_OUT, _CORRECTION_OUT if corrected else (),
                      _SWITCH_OUT if switched else (),
                      ("dhg",) if with_hourglass else ()):
            for name in names:
                if hasattr(b, name):
                    self._download("out_" + name, getattr(b, name), n_active)
        stream.synchronize()
