"""The runs whose results are pinned by ``tests/test_pinned_results.py``, and the script that
records them: ``python tests/pinned_runs.py`` rewrites ``tests/data/pinned_results.json``
from the code as it is (run it only for a change that is meant to change results, and say so
in the commit).

The AC runs' last digits depend on the machine as well as the code: on an AMD Zen 5
(llvmlite's host CPU ``znver5``) the same code gives the bars' profile oscillation 2.1e-11
and the shortened cantilever's momentum drift 1.3e-12 relative away from the values recorded
on the Zen 4 and Intel machines before it (the AV runs agree to 1e-13).  Not the compiled
code's target (``NUMBA_CPU_NAME=znver4`` on the Zen 5 gives the Zen 5's digits) nor
OpenBLAS's kernels (``OPENBLAS_CORETYPE``); the cause was not found (its file is of
generation 0, so it holds no run now; not re-measured since).  Since the pair pass
vectorises and fuses its sums (generation 2), a Zen 4 (``znver4``, 2026-12-06) gave the AC
bars' profile oscillation 1.2e-11 relative away from the shared file, recorded on an Intel
Xeon, and had a file of its own.  That cause was the vectors' width: LLVM vectorises with
512-bit vectors on a Zen 4 and 256-bit ones on the Intel Xeons, so a reassociated sum added
its lanes in another order.  Since ``import impactsph`` asks for 256-bit vectors on every
AVX-512 host (:mod:`impactsph.vectors`), the Zen 4 gives every number of the shared file to
the bit, and its file is gone (and so it does with its lanes loaded one by one instead of
gathered, ``prefer-no-gather``, which impactsph asks for there too; with
``IMPACTSPH_VECTORS=host`` it gives its own digits again, and its AC pins fail).  So a
machine whose CPU has a file of its own, ``tests/data/pinned_results.<cpu>.json`` (``python
tests/pinned_runs.py --this-cpu``, from a
commit whose results match the shared file elsewhere), is held to that file, and every other
machine to the shared one.

Each file carries the ``generation`` of the pins it was recorded from: re-recording the
shared file counts it up, and ``--this-cpu`` copies the shared file's.  A CPU file of an
older generation (its code's results were re-recorded since, elsewhere) cannot hold its CPU:
there the runs whose digits do not depend on the machine are held to the shared file and the
others (``MACHINE_DEPENDENT``) are skipped, saying how to re-record them on that CPU.

Each run is a built-in case with overrides (the Taylor bar and the cantilever shortened so
the whole set runs in seconds); what is pinned is every number of its summary that the
physics decides (not timings), and a few sums over the final state."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

RUNS = {
    "bars_av": ("bars", []),
    "bars_ac": ("bars", ["viscosity.scheme=\"ac\""]),
    "taylor_ac_short": ("taylor", ["time.end=10e-6"]),
    "taylor_av_short": ("taylor", ["time.end=10e-6", "viscosity.scheme=\"av\"",
                                   "viscosity.alpha1=0.5", "viscosity.alpha2=0.5"]),
    "cantilever_ac_short": ("cantilever", ["time.end=0.3e-3"]),
}

#: the runs whose last digits depend on the machine (the AC runs: the docstring)
MACHINE_DEPENDENT = {"bars_ac", "taylor_ac_short", "cantilever_ac_short"}
#: summary entries that measure the machine, not the physics
UNPINNED = {"wall_seconds", "compile_seconds", "setup_seconds", "pair_evaluations_per_second",
            "figures", "provenance", "device", "probes"}

DATA = Path(__file__).parent / "data" / "pinned_results.json"


def host_cpu() -> str:
    """The host CPU's name as LLVM knows it (``znver4``, ``sapphirerapids``, ...)."""
    import llvmlite.binding as llvm

    return llvm.get_host_cpu_name()


def cpu_data(cpu: str) -> Path:
    """The pins of the machines whose CPU is ``cpu`` (which may not exist)."""
    return DATA.with_name(f"pinned_results.{cpu}.json")


def generation(path: Path) -> int:
    """The generation of the pins in ``path`` (0 for a file from before generations, or none)."""
    return int(json.loads(path.read_text()).get("generation", 0)) if path.exists() else 0


def stale_cpu_file() -> Path | None:
    """This machine's CPU's own pins if they are of another generation than the shared ones."""
    own = cpu_data(host_cpu())
    return own if own.exists() and generation(own) != generation(DATA) else None


def pinned_file() -> Path:
    """The pins this machine is held to: its CPU's own file if there is one of the shared
    file's generation, else the shared file."""
    own = cpu_data(host_cpu())
    return own if own.exists() and own != stale_cpu_file() else DATA


def pinned_values(name: str) -> dict[str, float]:
    """Run ``RUNS[name]`` and return its pinned numbers."""
    from impactsph import Simulation, load_case

    try:
        from impactsph.problems import analyse
    except ImportError:  # the code before problems became modules (where the pins come from)
        from impactsph.analysis import analyse

    source, overrides = RUNS[name]
    case = load_case(source, overrides + ["output.figures=false"])
    sim = Simulation(case)
    sim.run()
    summary = {**sim.summary(), **analyse(case.analysis, sim)}
    out: dict[str, float] = {}
    for key, value in summary.items():
        if key in UNPINNED or value is None or isinstance(value, str):
            continue
        if isinstance(value, bool | int | float):
            out[key] = float(value)
    s = sim.state
    out["state_sum_abs_position"] = float(np.abs(s.position).sum())
    out["state_sum_abs_velocity"] = float(np.abs(s.velocity).sum())
    out["state_sum_density"] = float(s.density.sum())
    out["state_sum_specific_energy"] = float(s.specific_energy.sum())
    out["state_sum_abs_deviatoric_stress"] = float(np.abs(s.deviatoric_stress).sum())
    out["state_sum_plastic_work"] = float(s.plastic_work.sum())
    return out


def main(argv: list[str]) -> int:
    this_cpu = "--this-cpu" in argv
    target = cpu_data(host_cpu()) if this_cpu else DATA
    results: dict = {"generation": generation(DATA) + (0 if this_cpu else 1)}
    results.update({name: pinned_values(name) for name in RUNS})
    target.parent.mkdir(exist_ok=True)
    target.write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
