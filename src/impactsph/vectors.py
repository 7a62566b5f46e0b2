"""The width of the vectors in numba's compiled loops on x86-64 (``$IMPACTSPH_VECTORS``).

LLVM picks a vector width for each CPU model: for Intel's AVX-512 server cores (Skylake-SP
to Emerald Rapids) its tuning prefers 256-bit vectors (the target feature
``prefer-256-bit``), for AMD's Zen 4 and Zen 5 (``znver4``, ``znver5``) 512-bit ones. The
passes' neighbour loops are short (20-60 neighbours a particle) and gather each neighbour's
record; on a Zen 4 the 2D rate evaluation took 0.91-0.95 of its time with 256-bit vectors
and the pair pass 0.90-0.94, alternated in one sitting, and a paper's Taylor bar 0.91-0.94
(benchmarks/README.md, "256-bit vectors on a Zen 4"). The vectorised sums, which may be
reassociated (``PAIR_FASTMATH``), then add their lanes in the order they add in on an Intel
machine: the Zen 4 gives every pinned result of ``tests/pinned_runs.py`` to the bit of the
file recorded on an Intel Xeon, where with 512-bit vectors its AC runs differed from it by
up to 1.2e-11 relative and needed pins of their own.

So ``import impactsph`` (:func:`choose_vector_width`) asks numba for 256-bit vectors on an
x86-64 host with AVX-512, before numba compiles anything: ``NUMBA_CPU_FEATURES`` set to the
host's features (as numba would take them) plus ``+prefer-256-bit``, in the environment, so
that numba's later re-reading of its settings and the processes this one starts keep it.
It does nothing where

- ``$NUMBA_CPU_FEATURES`` is already set: numba's own setting wins, as set (a process
  started by one that made the choice inherits it this way);
- ``$IMPACTSPH_VECTORS=host``: LLVM's choice for the CPU (``256``, the default, asks for
  256-bit vectors; anything else is an error naming the variable);
- the host is not x86-64 or has no AVX-512: there is no wider vector to refuse;
- numba's compiler was already set up in the process (a ``numba.njit`` function defined
  before ``import impactsph``): its features are fixed then, so import impactsph first.

numba keys its on-disk cache by the features, so code compiled under one choice is not
served under the other. :func:`vector_width` says which choice the process's compiled code
was built with (every output's provenance records it)."""

from __future__ import annotations

import os
import platform
from collections.abc import Callable, MutableMapping

#: the environment variable that chooses (``256``, the default, or ``host``)
VECTORS_VARIABLE = "IMPACTSPH_VECTORS"
#: numba's own variable for the compiled code's CPU features
FEATURES_VARIABLE = "NUMBA_CPU_FEATURES"
#: LLVM's X86 tuning feature that keeps the vectoriser to 256-bit vectors
PREFER_256 = "+prefer-256-bit"


def _host_features() -> str:
    """The host's features as numba takes them (llvmlite's map, flattened, the AVX ones
    switched off where ``NUMBA_ENABLE_AVX=0``), e.g. ``"+avx512f,+fma,-amx-tile,..."``."""
    from numba.core.codegen import get_host_cpu_features

    return get_host_cpu_features()


def choose_vector_width(environ: MutableMapping[str, str] | None = None,
                        host_features: Callable[[], str] = _host_features,
                        machine: str | None = None) -> str:
    """Ask numba for 256-bit vectors where LLVM might use 512-bit ones (the module's
    docstring), by setting ``$NUMBA_CPU_FEATURES`` in ``environ`` (``os.environ``) and in
    numba's settings if numba is loaded; returns what was decided, a phrase for a log:
    ``"256-bit"``, or why nothing was set. ``host_features`` and ``machine``
    (``platform.machine()``) stand in for the host in tests. ``$IMPACTSPH_VECTORS`` other
    than ``256``, ``host`` or empty: ``ValueError`` naming it."""
    environ = os.environ if environ is None else environ
    choice = environ.get(VECTORS_VARIABLE, "").strip().lower()
    if choice not in ("", "256", "host"):
        raise ValueError(f"${VECTORS_VARIABLE} = {environ[VECTORS_VARIABLE]!r}: allowed are "
                         "256 (256-bit vectors on an AVX-512 host, the default) and host "
                         "(LLVM's own choice for the CPU)")
    if environ.get(FEATURES_VARIABLE, "").strip():
        return f"${FEATURES_VARIABLE} as set"
    if choice == "host":
        return f"LLVM's choice (${VECTORS_VARIABLE}=host)"
    machine = platform.machine() if machine is None else machine
    if machine.lower() not in ("x86_64", "amd64"):
        return f"LLVM's choice (not x86-64: {machine})"
    features = host_features()
    if "+avx512f" not in features.split(","):
        return "LLVM's choice (no AVX-512)"
    if environ is os.environ and _numba_compiler_ready():
        return "LLVM's choice (numba's compiler was set up before impactsph was imported)"
    chosen = f"{features},{PREFER_256}"
    environ[FEATURES_VARIABLE] = chosen
    if environ is os.environ:
        import sys

        config = sys.modules.get("numba.core.config")  # numba loaded: its settings too
        if config is not None:
            config.CPU_FEATURES = chosen
    return "256-bit"


def _numba_compiler_ready() -> bool:
    """Whether numba's CPU compiler exists in this process already, with the features it was
    made with (any ``numba.njit`` function defined before ``import impactsph`` makes it):
    then setting them changes nothing in this process. (numba's cached property of its CPU
    target; a numba without it reads as not ready, and :func:`vector_width` still tells.)"""
    import sys

    registry = sys.modules.get("numba.core.registry")
    target = getattr(registry, "cpu_target", None)
    return target is not None and "_toplevel_target_context" in vars(target)


def vector_width() -> str:
    """What numba's compiled code of this process was built for: ``"256-bit"``
    (``prefer-256-bit`` among the features it compiles with), ``"512-bit"`` (switched off),
    or ``"LLVM's choice for <cpu>"`` (neither: the CPU model's tuning decides)."""
    from numba.core.registry import cpu_target

    _, cpu, features = cpu_target.target_context.codegen().magic_tuple()
    listed = features.split(",")
    if PREFER_256 in listed:
        return "256-bit"
    if "-prefer-256-bit" in listed:
        return "512-bit"
    return f"LLVM's choice for {cpu}"


def cpu_name() -> str:
    """The CPU model numba compiles for (LLVM's name of the host, ``znver4``,
    ``emeraldrapids``, ..., or ``$NUMBA_CPU_NAME``)."""
    from numba.core.registry import cpu_target

    return cpu_target.target_context.codegen().magic_tuple()[1]
