"""How numba's compiled loops use the CPU's vectors on x86-64 (``$IMPACTSPH_VECTORS``).

LLVM tunes its vectoriser for each CPU model, and two of its choices cost the passes' short
neighbour loops (15-60 neighbours a particle, each neighbour's record gathered) on the
project's AMD machines (benchmarks/README.md, "256-bit vectors and no gathers on a Zen 4"):

- **The width.** For Intel's AVX-512 server cores (Skylake-SP to Emerald Rapids) LLVM prefers
  256-bit vectors (the target feature ``prefer-256-bit``), for AMD's Zen 4 and Zen 5
  (``znver4``, ``znver5``) 512-bit ones. On a Zen 4 the 2D rate evaluation took 0.89-0.97 of
  its 512-bit time with 256-bit vectors, the paper's Taylor bar and cantilever 0.90-0.93 on
  one thread. The vectorised sums, which may be reassociated (``PAIR_FASTMATH``), then add
  their lanes in the order they add in on an Intel machine: the Zen 4 gives every pinned
  result of ``tests/pinned_runs.py`` to the bit of the file recorded on an Intel Xeon, where
  with 512-bit vectors its AC runs differed from it by up to 1.2e-11 relative and needed pins
  of their own. So every AVX-512 host gets 256-bit vectors.
- **The gathers.** A Zen 4's gather instructions are slower than the loads they replace: with
  each lane loaded on its own (``prefer-no-gather``) its 2D rate evaluation took a further
  0.78-0.83 of its time, to 2.1e8 pair evaluations a second on two threads. The loads bring
  the same numbers into the same lanes: the same bits (every pinned result, and
  ``benchmarks/same_bits.py``'s ten cases). Only where measured: :data:`NO_GATHER_CPUS`
  (not Intel's cores, whose gathers are faster, nor AMD's other models, none measured).

So ``import impactsph`` (:func:`choose_vector_width`) sets ``NUMBA_CPU_FEATURES`` to the host's
features (as numba would take them) and :func:`tuning` 's for its CPU model, before numba
compiles anything, in the environment, so that numba's later re-reading of its settings and
the processes this one starts keep it. It does nothing where

- ``$NUMBA_CPU_FEATURES`` is already set: numba's own setting wins, as set (a process started
  by one that made the choice inherits it this way);
- ``$IMPACTSPH_VECTORS=host``: LLVM's own choices for the CPU (``tuned``, the default, makes
  the choices above; anything else is an error naming the variable);
- the host is not x86-64, or its model needs neither choice (no AVX-512 and not in
  :data:`NO_GATHER_CPUS`);
- numba's compiler was already set up in the process (a ``numba.njit`` function defined
  before ``import impactsph``): its features are fixed then, so import impactsph first.

numba keys its on-disk cache by the features, so code compiled under one choice is not
served under the other. :func:`vector_width` says what the process's compiled code was built
with (every output's provenance records it, beside :func:`cpu_name`)."""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import Callable, MutableMapping

#: the environment variable that chooses (``tuned``, the default, or ``host``)
VECTORS_VARIABLE = "IMPACTSPH_VECTORS"
#: numba's own variable for the compiled code's CPU features
FEATURES_VARIABLE = "NUMBA_CPU_FEATURES"
#: LLVM's X86 tuning feature that keeps the vectoriser to 256-bit vectors
PREFER_256 = "+prefer-256-bit"
#: LLVM's X86 tuning feature that loads a vector's lanes one by one instead of gathering them
NO_GATHER = "+prefer-no-gather"
#: the CPU models (llvmlite's names) whose loops run faster without gathers, as measured
NO_GATHER_CPUS = frozenset({"znver4"})


def _host_features() -> str:
    """The host's features as numba takes them (llvmlite's map, flattened, the AVX ones
    switched off where ``NUMBA_ENABLE_AVX=0``), e.g. ``"+avx512f,+fma,-amx-tile,..."``."""
    from numba.core.codegen import get_host_cpu_features

    return get_host_cpu_features()


def _host_cpu() -> str:
    """The CPU model numba compiles for, as its compiler takes it: ``$NUMBA_CPU_NAME``
    (numba's setting), else LLVM's name of the host."""
    import llvmlite.binding as llvm
    from numba.core import config

    return config.CPU_NAME or llvm.get_host_cpu_name()


def tuning(cpu: str, features: str) -> list[str]:
    """The features added for CPU model ``cpu`` with host features ``features`` (the module's
    docstring): ``+prefer-256-bit`` where there is AVX-512, ``+prefer-no-gather`` on the
    models of :data:`NO_GATHER_CPUS`."""
    listed = features.split(",")
    added = []
    if "+avx512f" in listed:
        added.append(PREFER_256)
    if cpu in NO_GATHER_CPUS and "+avx2" in listed:
        added.append(NO_GATHER)
    return added


def choose_vector_width(environ: MutableMapping[str, str] | None = None,
                        host_features: Callable[[], str] = _host_features,
                        machine: str | None = None,
                        host_cpu: Callable[[], str] = _host_cpu) -> str:
    """Make the choices of the module's docstring by setting ``$NUMBA_CPU_FEATURES`` in
    ``environ`` (``os.environ``) and in numba's settings if numba is loaded; returns what was
    decided, a phrase for a log: the features added (``"+prefer-256-bit,+prefer-no-gather"``),
    or why nothing was set. ``host_features``, ``machine`` (``platform.machine()``) and
    ``host_cpu`` stand in for the host in tests. ``$IMPACTSPH_VECTORS`` other than ``tuned``,
    ``host`` or empty: ``ValueError`` naming it."""
    environ = os.environ if environ is None else environ
    choice = environ.get(VECTORS_VARIABLE, "").strip().lower()
    if choice not in ("", "tuned", "host"):
        raise ValueError(f"${VECTORS_VARIABLE} = {environ[VECTORS_VARIABLE]!r}: allowed are "
                         "tuned (the measured choices for the CPU: 256-bit vectors on an "
                         "AVX-512 host, loads for gathers on a Zen 4; the default) and host "
                         "(LLVM's own choices for the CPU)")
    if environ.get(FEATURES_VARIABLE, "").strip():
        return f"${FEATURES_VARIABLE} as set"
    if choice == "host":
        return f"LLVM's choice (${VECTORS_VARIABLE}=host)"
    machine = platform.machine() if machine is None else machine
    if machine.lower() not in ("x86_64", "amd64"):
        return f"LLVM's choice (not x86-64: {machine})"
    features = host_features()
    added = tuning(host_cpu(), features)
    if not added:
        return "LLVM's choice (nothing to change for this CPU)"
    if environ is os.environ and _numba_compiler_ready():
        return "LLVM's choice (numba's compiler was set up before impactsph was imported)"
    chosen = ",".join([features, *added])
    environ[FEATURES_VARIABLE] = chosen
    if environ is os.environ:
        config = sys.modules.get("numba.core.config")  # numba loaded: its settings too
        if config is not None:
            config.CPU_FEATURES = chosen
    return ",".join(added)


def _numba_compiler_ready() -> bool:
    """Whether numba's CPU compiler exists in this process already, with the features it was
    made with (any ``numba.njit`` function defined before ``import impactsph`` makes it):
    then setting them changes nothing in this process. (numba's cached property of its CPU
    target; a numba without it reads as not ready, and :func:`vector_width` still tells.)"""
    registry = sys.modules.get("numba.core.registry")
    target = getattr(registry, "cpu_target", None)
    return target is not None and "_toplevel_target_context" in vars(target)


def vector_width() -> str:
    """What numba's compiled code of this process was built for: ``"256-bit"`` or
    ``"512-bit"`` (``prefer-256-bit`` among the features it compiles with, or switched off),
    else ``"LLVM's choice for <cpu>"``; with ``", no gathers"`` where ``prefer-no-gather`` is
    among them."""
    cpu, features = _compiled_for()
    if PREFER_256 in features:
        width = "256-bit"
    elif "-prefer-256-bit" in features:
        width = "512-bit"
    else:
        width = f"LLVM's choice for {cpu}"
    return width + (", no gathers" if NO_GATHER in features else "")


def cpu_name() -> str:
    """The CPU model numba compiles for (LLVM's name of the host, ``znver4``,
    ``emeraldrapids``, ..., or ``$NUMBA_CPU_NAME``)."""
    return _compiled_for()[0]


def _compiled_for() -> tuple[str, list[str]]:
    """The CPU model and the features of numba's compiler in this process (its cache key,
    ``magic_tuple``)."""
    from numba.core.registry import cpu_target

    _, cpu, features = cpu_target.target_context.codegen().magic_tuple()
    return cpu, features.split(",")
