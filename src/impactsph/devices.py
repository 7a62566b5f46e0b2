"""Choice of the device that runs the rate passes: the CPU, or an NVIDIA GPU where present."""

from __future__ import annotations

import logging

from .physics.options import PassOptions
from .physics.rates import CpuRates

log = logging.getLogger(__name__)


def select_backend(device: str, dim: int, options: PassOptions | str | None = None,
                   cpu_only: str | None = None):
    """A rate backend for ``device`` (``"cpu"`` or ``"gpu"``), its passes compiled with the
    compile-time ``options`` (:class:`~impactsph.physics.options.PassOptions`: the
    ``[stabilisation]`` and ``[contact]`` tables, docs/stabilisation.md).

    ``"gpu"`` without a usable GPU (no CUDA driver, no device, or numba-cuda missing), or for a
    case with something that runs on the CPU only (``cpu_only`` says what), logs a warning
    that says why and returns the CPU backend: a case written for a GPU still runs."""
    if device == "cpu":
        return CpuRates(dim, options)
    if device != "gpu":
        raise ValueError(f"compute.device = {device!r}: allowed are 'cpu' and 'gpu'")
    if cpu_only is not None:
        log.warning("compute.device = 'gpu' but %s; running on the CPU", cpu_only)
        return CpuRates(dim, options)
    from . import gpu

    reason = gpu.unavailable_reason()
    if reason is not None:
        log.warning("compute.device = 'gpu' but %s; running on the CPU", reason)
        return CpuRates(dim, options)
    return gpu.GpuRates(dim, options)
