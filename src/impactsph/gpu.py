"""The rate passes on an NVIDIA GPU (numba-cuda).  Work in progress: see GpuRates."""

from __future__ import annotations


def unavailable_reason() -> str | None:
    """Why no GPU can be used here, or ``None`` when one can."""
    try:
        from numba import cuda
    except ImportError as exc:  # pragma: no cover - numba-cuda missing
        return f"numba-cuda is not installed ({exc})"
    try:
        if not cuda.is_available():
            return "no CUDA GPU or driver was found"
    except Exception as exc:  # noqa: BLE001 - any driver error means no GPU
        return f"the CUDA driver failed ({exc})"
    return None
