"""impactsph: smoothed particle hydrodynamics for solids under impact.

Python API::

    from impactsph import load_case, Simulation, run_case
    case = load_case("bars", ["viscosity.alpha1=0.3"])
    summary = run_case(case, "runs/bars")       # everything, outputs and figures
    sim = Simulation(case); sim.run(t_end=5e-6)  # or step by step, state in sim.state
"""

import os as _os

# The numba kernels run in many short parallel regions per time step.  GNU OpenMP lets idle
# threads spin only ~1000 iterations before sleeping when it counts more threads than cores
# (numba's pool plus the calling thread), and waking them costs ~150 us per region: 3x the
# run time of the paper's 2D examples.  Spinning for ~100 us between regions removes that.
# Set before numba loads libgomp; a value already in the environment wins.
_os.environ.setdefault("GOMP_SPINCOUNT", "100000")

# 256-bit vectors on an AVX-512 host (AMD's Zen 4 and 5 would get 512-bit ones), and on a Zen 4
# loads in place of its slow gathers: the passes' short neighbour loops run faster so, and
# their sums give an Intel machine's bits (impactsph.vectors).  Before numba compiles
# anything; $NUMBA_CPU_FEATURES, if set, wins, and IMPACTSPH_VECTORS=host leaves it to LLVM.
from .vectors import choose_vector_width as _choose_vector_width  # noqa: E402

_choose_vector_width()


def _preload_tbb() -> None:
    """With ``NUMBA_THREADING_LAYER=tbb``, load the TBB library that ``pip install tbb`` puts
    in the environment's ``lib`` folder (not on the loader's path), so numba finds it.

    OpenMP (the default) is the faster on an idle machine; TBB's work stealing keeps going
    when another process holds a core, where OpenMP's barriers wait for a descheduled thread
    (measured in benchmarks/README.md)."""
    if _os.environ.get("NUMBA_THREADING_LAYER", "").lower() != "tbb":
        return
    import ctypes
    import sys

    for name in ("libtbb.so.12", "libtbb.12.dylib"):
        path = _os.path.join(sys.prefix, "lib", name)
        if _os.path.exists(path):
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            return


_preload_tbb()

from .jitcache import copy_sets_of_names_shallowly as _copy_sets_of_names_shallowly  # noqa: E402
from .jitcache import inline_fresh_ir_in_place as _inline_fresh_ir_in_place  # noqa: E402
from .jitcache import lock_cache_writes as _lock_cache_writes  # noqa: E402
from .jitcache import stamp_package_sources as _stamp_package_sources  # noqa: E402

_lock_cache_writes()  # numba's cache safe between processes (impactsph.jitcache)
# the package's own cached kernels stale when any of its files changes (the same)
_stamp_package_sources(_os.path.dirname(__file__))
_inline_fresh_ir_in_place()  # numba's inliner without its unread copies (impactsph.jitcache)
_copy_sets_of_names_shallowly()  # numba's copy propagation without deep copies (the same)
if _os.environ.get("IMPACTSPH_COMPILE_LOG"):  # what each process compiles, for how long
    from .jitcache import log_compiles as _log_compiles

    _log_compiles(_os.environ["IMPACTSPH_COMPILE_LOG"])

from ._version import __version__  # noqa: E402
from .config import Case, CaseError  # noqa: E402
from .loading import load_case  # noqa: E402
from .runner import run_case  # noqa: E402
from .simulation import Simulation, SimulationError  # noqa: E402

__all__ = ["Case", "CaseError", "Simulation", "SimulationError", "__version__", "load_case",
           "run_case"]
