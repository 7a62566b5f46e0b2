"""Speed of the rate evaluation, the neighbour-list build and the time step.

For each dimension and size N a lattice of about N steel-like particles (dx = 1 mm,
h = 1.2 dx, elastic, linear EOS) with small random velocities (so that the artificial
viscosity is active) is set up through the public API, and the script times

* one rate evaluation, ``sim.solver.rates(sim.state)``: neighbour-list update (a
  displacement check; the particles do not move, so no rebuild) and the three passes;
* one full neighbour-list rebuild, ``NeighbourList.build(x, 2 h, 0.2 h)``;
* one integrator step (two rate evaluations plus the state updates);

taking the best of ``--repeat`` runs of each, and runs the built-in ``bars`` case end to
end.  A *pair evaluation* is one ordered neighbour pair (i, j) with ``|x_i - x_j| < 2h``
processed by the pair pass of one rate evaluation.

Usage::

    python benchmarks/bench_rates.py                      # 2D, N = 1e4, 1e5, 1e6
    python benchmarks/bench_rates.py --sizes 1e4 --dims 1 2 3 --json rates.json
"""

from __future__ import annotations

import argparse
import datetime as _dt
import gc
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time

import numba
import numpy as np

import impactsph
from impactsph.config import load_case, validate_case
from impactsph.integrate import stable_time_step
from impactsph.neighbours import NeighbourList
from impactsph.simulation import Simulation

DX = 1e-3  # m
H_OVER_DX = 1.2
SEED = 20240601


def peak_rss_mib() -> float:
    """Peak resident set size of this process so far (MiB; ru_maxrss is KiB on Linux)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def cpu_busy_seconds() -> float | None:
    """CPU seconds spent busy by the whole machine since boot (Linux ``/proc/stat``), or None."""
    try:
        with open("/proc/stat") as fh:
            fields = fh.readline().split()[1:]
        user, nice, system, _idle, _iowait, irq, softirq = (int(v) for v in fields[:7])
        steal = int(fields[7]) if len(fields) > 7 else 0
        return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError):
        return None


def own_cpu_seconds() -> float:
    """CPU seconds used by this process (all threads)."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def other_load(seconds: float = 1.0) -> float | None:
    """Cores kept busy by other processes over a short window (None if unknown)."""
    b0, o0, t0 = cpu_busy_seconds(), own_cpu_seconds(), time.perf_counter()
    if b0 is None:
        return None
    time.sleep(seconds)
    b1, o1 = cpu_busy_seconds(), own_cpu_seconds()
    return max(0.0, (b1 - b0) - (o1 - o0)) / (time.perf_counter() - t0)


def lattice_side(n: int, dim: int) -> int:
    """Particles per axis of a square/cubic/line lattice of about ``n`` particles."""
    return max(1, round(n ** (1.0 / dim)))


def make_case(n: int, dim: int) -> dict:
    """A case dict: one steel block of about ``n`` particles, at rest."""
    side = lattice_side(n, dim)
    return {
        "name": f"bench_{dim}d_{n}",
        "dimension": dim,
        "materials": {"steel": {"model": "elastic", "density": 7850.0,
                                "youngs_modulus": 2e11, "poisson_ratio": 0.3,
                                "eos": "linear"}},
        "bodies": [{"name": "block", "material": "steel",
                    "geometry": {"origin": [0.0] * dim, "size": [side * DX] * dim,
                                 "spacing": DX},
                    "velocity": [0.0] * dim}],
        "kernel": {"h_over_dx": H_OVER_DX},
        "time": {"end": 1e-6},
        "output": {"figures": False},
    }


def best_of(fn, repeat: int) -> float:
    """Smallest wall time (s) of ``repeat`` calls of ``fn()``."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_size(n_target: int, dim: int, repeat: int) -> dict:
    """Time rates, neighbour rebuild and a step for one lattice."""
    t0 = time.perf_counter()
    sim = Simulation(validate_case(make_case(n_target, dim)))
    setup = time.perf_counter() - t0
    state = sim.state
    rng = np.random.default_rng(SEED)
    state.velocity[:] = rng.normal(0.0, 1.0, size=state.velocity.shape)  # ~1 m/s

    sim.solver.rates(state)  # warm: the new velocities, caches
    t_rates = best_of(lambda: sim.solver.rates(state), repeat)
    pairs = int(sim.solver.buffers.pair_count[: state.n].sum())  # real particles only

    h = float(state.smoothing_length.max())
    nl = NeighbourList.build(state.position, support=2.0 * h, skin=0.2 * h)  # warm
    stored_pairs = nl.n_pairs
    del nl
    t_build = best_of(
        lambda: NeighbourList.build(state.position, support=2.0 * h, skin=0.2 * h), repeat)

    dt = stable_time_step(state, sim.problem.table, 0.3)
    builds_before = sim.solver.neighbours.builds
    sim.integrator.step(state, dt)  # warm: compiles (or loads) the integrator kernels
    t_step = best_of(lambda: sim.integrator.step(state, dt), repeat)
    rebuilds_in_steps = sim.solver.neighbours.builds - builds_before

    result = {
        "dimension": dim,
        "n_target": n_target,
        "n_particles": state.n,
        "setup_seconds": setup,
        "pairs_per_rate_evaluation": pairs,
        "pairs_per_particle": pairs / state.n,
        "stored_pairs_in_rebuild": stored_pairs,
        "rate_seconds": t_rates,
        "pair_evaluations_per_second": pairs / t_rates,
        "neighbour_rebuild_seconds": t_build,
        "dt": dt,
        "step_seconds": t_step,
        "step_over_two_rates": t_step / (2.0 * t_rates),
        "neighbour_rebuilds_during_steps": rebuilds_in_steps,
        "peak_rss_mib_so_far": peak_rss_mib(),
    }
    return result


def bench_bars() -> dict:
    """The built-in bars case, end to end (``Simulation.run``)."""
    t0 = time.perf_counter()
    sim = Simulation(load_case("bars"))
    setup = time.perf_counter() - t0
    sim.run()
    s = sim.summary()
    return {"n_particles": s["n_particles"], "n_steps": s["n_steps"],
            "setup_seconds": setup, "wall_seconds": s["wall_seconds"],
            "seconds_per_step": s["wall_seconds"] / s["n_steps"],
            "pair_evaluations": s["pair_evaluations"],
            "pair_evaluations_per_second": s["pair_evaluations_per_second"],
            "neighbour_list_builds": s["neighbour_list_builds"]}


def fit_exponent(ns: list[int], ts: list[float]) -> float:
    """Least-squares slope of log t against log N."""
    slope, _ = np.polyfit(np.log(ns), np.log(ts), 1)
    return float(slope)


def source_version() -> str:
    """``impactsph`` version and, in a git checkout, the commit (``+dirty`` if modified)."""
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here,
                                capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ":/src"],
            cwd=here, capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "", ""
    version = f"impactsph {impactsph.__version__}"
    return f"{version} ({commit}{'+dirty src' if dirty.strip() else ''})" if commit else version


def machine_info() -> dict:
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {"date": _dt.datetime.now().isoformat(timespec="seconds"),
            "source": source_version(),
            "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "numba_threads": numba.get_num_threads(),
            "numba_threading_layer_env": os.environ.get("NUMBA_THREADING_LAYER", ""),
            "cpu_count": os.cpu_count(), "usable_cores": usable,
            "other_load_at_start": other_load(),
            "processor": platform.processor() or platform.machine()}


def _si(x: float) -> str:
    return f"{x:.3g}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5, 1e6],
                    help="target particle counts (default: 1e4 1e5 1e6)")
    ap.add_argument("--dims", nargs="+", type=int, choices=(1, 2, 3), default=[2],
                    help="dimensions (default: 2)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per quantity; best kept")
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument("--no-bars", action="store_true", help="skip the bars case")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    sizes = sorted({int(round(s)) for s in args.sizes})
    if sizes[0] < 1:
        ap.error("--sizes must be >= 1")

    info = machine_info()
    start, busy0, own0 = time.perf_counter(), cpu_busy_seconds(), own_cpu_seconds()
    print(f"impactsph rate benchmark  {info['date']}  {info['source']}")
    print(f"python {info['python']}  numpy {info['numpy']}  numba {info['numba']}  "
          f"({info['processor']})")
    print(f"numba threads: {info['numba_threads']}   cores: {info['cpu_count']} "
          f"(usable {info['usable_cores']})")
    if info["other_load_at_start"] is not None and info["other_load_at_start"] > 0.2:
        print(f"WARNING: other processes keep {info['other_load_at_start']:.2f} cores busy; "
              "competition for the cores slows numba's parallel regions a lot")
    print(f"lattice dx = {DX:g} m, h = {H_OVER_DX} dx, steel (7850 kg/m^3, E = 2e11 Pa, "
          f"nu = 0.3), random v ~ N(0, 1 m/s), best of {args.repeat}")
    print()

    results: dict = {"machine": info, "repeat": args.repeat, "sizes": [], "fits": {}}
    header = (f"{'dim':>3} {'N':>9} {'pairs/i':>7} {'rates s':>9} {'pairs/s':>9} "
              f"{'rebuild s':>9} {'step s':>9} {'step/2r':>7} {'setup s':>7} {'RSS MiB':>8}")
    print(header)
    print("-" * len(header))
    for dim in args.dims:
        rows = []
        for n in sizes:
            r = bench_size(n, dim, args.repeat)
            gc.collect()  # free the previous lattice before the next, larger one
            rows.append(r)
            results["sizes"].append(r)
            print(f"{dim:>3} {r['n_particles']:>9} {r['pairs_per_particle']:>7.2f} "
                  f"{_si(r['rate_seconds']):>9} {_si(r['pair_evaluations_per_second']):>9} "
                  f"{_si(r['neighbour_rebuild_seconds']):>9} {_si(r['step_seconds']):>9} "
                  f"{r['step_over_two_rates']:>7.2f} {r['setup_seconds']:>7.1f} "
                  f"{r['peak_rss_mib_so_far']:>8.0f}", flush=True)
        if len(rows) >= 2:
            ns = [r["n_particles"] for r in rows]
            fit = {"rates": fit_exponent(ns, [r["rate_seconds"] for r in rows]),
                   "neighbour_rebuild": fit_exponent(
                       ns, [r["neighbour_rebuild_seconds"] for r in rows]),
                   "step": fit_exponent(ns, [r["step_seconds"] for r in rows])}
            results["fits"][str(dim)] = fit
            print(f"    {dim}D fit t ~ N^p:  rates p = {fit['rates']:.3f}   "
                  f"rebuild p = {fit['neighbour_rebuild']:.3f}   step p = {fit['step']:.3f}")
    print()
    print("pairs/i: pair evaluations per particle per rate evaluation (|r_ij| < 2h); "
          "rates s: one rate")
    print("evaluation (neighbour update check + 3 passes); pairs/s: pair evaluations per "
          "second;")
    print("rebuild s: NeighbourList.build(x, 2h, 0.2h); step s: one midpoint step; "
          "step/2r: step / (2 rates s);")
    print("RSS: peak resident set size of the process so far.")

    if not args.no_bars:
        b = bench_bars()
        results["bars"] = b
        print()
        print(f"bars case (1D, {b['n_particles']} particles): {b['n_steps']} steps in "
              f"{b['wall_seconds']:.3f} s ({b['seconds_per_step'] * 1e6:.0f} us/step, "
              f"setup {b['setup_seconds']:.2f} s), "
              f"{_si(b['pair_evaluations_per_second'])} pair evaluations/s")

    results["peak_rss_mib"] = peak_rss_mib()
    total = results["total_seconds"] = time.perf_counter() - start
    busy1 = cpu_busy_seconds()
    others = (None if busy0 is None or busy1 is None else
              max(0.0, (busy1 - busy0) - (own_cpu_seconds() - own0)) / total)
    results["other_load_during_run"] = others
    print(f"\npeak RSS {results['peak_rss_mib']:.0f} MiB, total {total:.1f} s"
          + ("" if others is None else f", other processes used {others:.2f} cores on average"))
    if others is not None and others > 0.2:
        print("WARNING: the timings above were taken while other processes competed for the "
              "cores; rerun on an idle machine")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
