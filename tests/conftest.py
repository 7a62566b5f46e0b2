"""Shared helpers: running the bars case with overrides (cached per parameter set)."""

from __future__ import annotations

import os

if os.environ.get("PYTEST_XDIST_WORKER"):  # one of pytest-xdist's workers (-n): numba gets
    # this worker's share of the cores, so the workers' threads do not contend for them
    # (OpenMP's barriers collapse when they do: benchmarks/README.md)
    _workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    _cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    os.environ["NUMBA_NUM_THREADS"] = str(max(1, (_cores or 1) // _workers))

# the generated passes compiled without numba's parallel transform (impactsph.physics.options.
# parallel_default): the same results to the bit, the pair pass compiled in about 40% of the
# time (compiling is most of this suite's time from a cold cache), running as fast on one
# thread (impactsph.physics.borrow).  The workers run one thread each (above), so the threads'
# code would mostly have cost compile time; tests/test_parallel_passes.py and test_threads.py
# compile the threaded passes and check them against these.  IMPACTSPH_PARALLEL=1 runs the
# whole suite on the threaded passes.
os.environ.setdefault("IMPACTSPH_PARALLEL", "0")

from functools import cache  # noqa: E402

import pytest

from impactsph.loading import load_case
from impactsph.problems import analyse
from impactsph.simulation import Simulation


@cache
def _bars(overrides: tuple[str, ...]):
    case = load_case("bars", list(overrides))
    sim = Simulation(case)
    sim.run()
    return sim, {**sim.summary(), **analyse("bars", sim)}


@pytest.fixture(scope="session")
def run_bars():
    """``run_bars(*overrides) -> (simulation, summary)``, each parameter set run once."""

    def run(*overrides: str):
        return _bars(tuple(overrides))

    return run


@pytest.fixture(scope="session")
def benchmark_script():
    """``benchmark_script(name)``: the module ``benchmarks/<name>.py`` (the benchmarks are
    scripts, not a package), loaded from its file."""
    import importlib.util
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "benchmarks"

    def load(name: str):
        spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load
