"""Speed of the rate evaluation, the neighbour-list build and the time step.

For each dimension and size N a lattice of about N steel-like particles (dx = 1 mm,
h = 1.2 dx, elastic, linear EOS) with small random velocities (so that the artificial
viscosity is active) is set up through the public API, and the script times

* one rate evaluation, ``sim.solver.rates(sim.state)``: neighbour-list update (a
  displacement check; the particles do not move, so no rebuild) and the three passes;
* one full neighbour-list rebuild, ``NeighbourList.build(x, 2 h, 0.2 h)``;
* one integrator step (two rate evaluations plus the state updates);

taking the best of ``--repeat`` runs of each, with all threads and with one (the ratio is
the parallel speed-up).  Each size runs in a fresh process, so that its memory is its own:
*bytes per particle* is the growth of the peak resident set from just before the lattice is
built (numba's code already loaded) to the end, divided by N.  Then the paper's three
examples run end to end (``--examples``), and numba's one-time compilation is timed in a
process with an empty cache (``--compile``).  A *pair evaluation* is one ordered neighbour
pair (i, j) with ``|x_i - x_j| < 2h`` processed by the pair pass of one rate evaluation.

Usage::

    python benchmarks/bench_rates.py              # 2D and 3D, N = 1e4, 1e5, 1e6, examples
    python benchmarks/bench_rates.py --sizes 1e4 --dims 1 2 3 --examples bars --json r.json
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
import tempfile
import time

import numba
import numpy as np

import impactsph
from impactsph.integrate import stable_time_step
from impactsph.loading import load_case, validate_case
from impactsph.neighbours import NeighbourList
from impactsph.simulation import Simulation, compile_kernels

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
    """CPU seconds used by this process (all threads) and its finished children (the
    benchmark items run in child processes)."""
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        ru = resource.getrusage(who)
        total += ru.ru_utime + ru.ru_stime
    return total


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


#: what the lattices run: "paper" (the paper's scheme, the equations of the naive yardstick
#: ``../shared/bench/naive_pairs.py``) or "defaults" (the case defaults: for this elastic
#: block the stabilisation 'auto' turns on the corrected forces and the hourglass control)
SCHEME_ENV = "IMPACTSPH_BENCH_SCHEME"
#: how the lattices' particles are numbered (``compute.particle_order``: "auto", the
#: default's choice, "input", the lattice's own row-major order, or "cells", the neighbour
#: list's)
ORDER_ENV = "IMPACTSPH_BENCH_PARTICLE_ORDER"


def make_case(n: int, dim: int) -> dict:
    """A case dict: one steel block of about ``n`` particles, at rest, with the scheme that
    ``$IMPACTSPH_BENCH_SCHEME`` names (:data:`SCHEME_ENV`) and the particle order that
    ``$IMPACTSPH_BENCH_PARTICLE_ORDER`` names (:data:`ORDER_ENV`)."""
    side = lattice_side(n, dim)
    paper = os.environ.get(SCHEME_ENV, "paper") == "paper"
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
        "compute": {"particle_order": os.environ.get(ORDER_ENV, "auto")},
        **({"stabilisation": {"gradient_correction": "none", "hourglass": 0.0}}
           if paper else {}),
    }


def best_of(fn, repeat: int) -> float:
    """Smallest wall time (s) of ``repeat`` calls of ``fn()``."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def current_rss_mib() -> float:
    """Resident set size of this process now (MiB), from /proc (0 where unknown)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        return 0.0


def bench_size(n_target: int, dim: int, repeat: int) -> dict:
    """Time rates, neighbour rebuild and a step for one lattice."""
    warm = Simulation(validate_case(make_case(2**dim, dim)))  # load the compiled code
    warm.integrator.step(warm.state, 1e-9)
    del warm
    gc.collect()
    baseline = current_rss_mib()
    t0 = time.perf_counter()
    sim = Simulation(validate_case(make_case(n_target, dim)))
    setup = time.perf_counter() - t0
    state = sim.state
    rng = np.random.default_rng(SEED)
    state.velocity[:] = rng.normal(0.0, 1.0, size=state.velocity.shape)  # ~1 m/s

    sim.solver.rates(state)  # warm: the new velocities, caches
    t_rates = best_of(lambda: sim.solver.rates(state), repeat)
    pairs = int(sim.solver.buffers.pair_count[: state.n].sum())  # real particles only
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    t_rates_1 = best_of(lambda: sim.solver.rates(state), repeat)
    numba.set_num_threads(threads)

    dt = stable_time_step(state, sim.problem.table, 0.3)
    builds_before = sim.solver.neighbours.builds
    sim.integrator.step(state, dt)  # warm: compiles (or loads) the integrator kernels
    t_step = best_of(lambda: sim.integrator.step(state, dt), repeat)
    rebuilds_in_steps = sim.solver.neighbours.builds - builds_before

    # the run's own memory: before the extra neighbour list built for timing below
    bytes_per_particle = (peak_rss_mib() - baseline) * 2**20 / state.n
    h = float(state.smoothing_length.max())
    nl = NeighbourList.build(state.position, support=2.0 * h, skin=0.2 * h)  # warm
    stored_pairs = nl.n_pairs
    del nl
    t_build = best_of(
        lambda: NeighbourList.build(state.position, support=2.0 * h, skin=0.2 * h), repeat)

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
        "rate_seconds_one_thread": t_rates_1,
        "parallel_speedup": t_rates_1 / t_rates,
        "neighbour_rebuild_seconds": t_build,
        "dt": dt,
        "step_seconds": t_step,
        "step_over_two_rates": t_step / (2.0 * t_rates),
        "neighbour_rebuilds_during_steps": rebuilds_in_steps,
        "peak_rss_mib": peak_rss_mib(),
        "bytes_per_particle": bytes_per_particle,
    }
    return result


def child(argv: list[str]) -> dict:
    """Run one benchmark item in this (fresh) process; see :func:`in_child`."""
    kind = argv[0]
    if kind == "size":
        return bench_size(int(argv[1]), int(argv[2]), int(argv[3]))
    if kind == "example":
        return bench_example(argv[1], *argv[2:])
    if kind == "compile":
        return bench_compile()
    raise SystemExit(f"unknown child item {kind!r}")


def in_child(*item: object, env: dict | None = None) -> dict:
    """Run ``child(item)`` in a new Python process and return its JSON result."""
    out = subprocess.run([sys.executable, os.path.abspath(__file__), "--child",
                          *map(str, item)], capture_output=True, text=True,
                         env={**os.environ, **(env or {})})
    if out.returncode != 0:
        raise RuntimeError(f"benchmark item {item} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_example(name: str, *overrides: str) -> dict:
    """A built-in case end to end (``Simulation.run``), without its reference run."""
    case = load_case(name, list(overrides))
    case = case.model_copy(update={"output": case.output.model_copy(
        update={"reference_viscosity": None, "figures": False})})
    t0 = time.perf_counter()
    sim = Simulation(case)
    setup = time.perf_counter() - t0
    sim.run()
    s = sim.summary()
    return {"case": name, "dimension": case.dimension, "scheme": case.viscosity.scheme,
            "n_particles": s["n_particles"], "n_steps": s["n_steps"],
            "setup_seconds": setup, "wall_seconds": s["wall_seconds"],
            "seconds_per_step": s["wall_seconds"] / s["n_steps"],
            "pair_evaluations": s["pair_evaluations"],
            "pair_evaluations_per_second": s["pair_evaluations_per_second"],
            "neighbour_list_builds": s["neighbour_list_builds"]}


def bench_compile() -> dict:
    """Time to a first step of each dimension's solver (AC, a wall) in this process; run
    with an empty ``NUMBA_CACHE_DIR`` it is numba's one-time compilation."""
    out = {}
    for dim in (1, 2, 3):
        t0 = time.perf_counter()
        compile_kernels(dim)
        out[f"{dim}d_seconds"] = time.perf_counter() - t0
    return out


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
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--child":
        print(json.dumps(child(sys.argv[2:])))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5, 1e6],
                    help="target particle counts (default: 1e4 1e5 1e6)")
    ap.add_argument("--dims", nargs="+", type=int, choices=(1, 2, 3), default=[2, 3],
                    help="dimensions (default: 2 3)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per quantity; best kept")
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument("--examples", nargs="*", default=["bars", "taylor", "cantilever"],
                    choices=("bars", "taylor", "cantilever"),
                    help="built-in cases to run end to end (default: all three; the "
                         "cantilever takes minutes)")
    ap.add_argument("--skins", nargs="*", type=float, default=[0.0, 0.05, 0.1, 0.2],
                    help="neighbour skins (fractions of the support) at which the taylor case "
                         "also runs, to show what reusing the list saves (default: 0 0.05 0.1 "
                         "0.2; none to skip)")
    ap.add_argument("--scheme", choices=("paper", "defaults"), default="paper",
                    help="the lattices' scheme: the paper's (default; the naive yardstick's "
                    "equations) or the case defaults (an elastic block: corrected forces and "
                    "hourglass control)")
    ap.add_argument("--particle-order", choices=("auto", "input", "cells"), default="auto",
                    help="the lattices' compute.particle_order: the default's choice (auto: "
                    "the list's order for 2D lattices of 5e5 particles or more), their own "
                    "row-major numbering (input) or the neighbour list's cells' (cells)")
    ap.add_argument("--no-compile", action="store_true",
                    help="skip timing numba's compilation with an empty cache")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    sizes = sorted({int(round(s)) for s in args.sizes})
    if sizes[0] < 1:
        ap.error("--sizes must be >= 1")

    os.environ[SCHEME_ENV] = args.scheme  # the children inherit them
    os.environ[ORDER_ENV] = args.particle_order
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
          f"nu = 0.3), random v ~ N(0, 1 m/s), AV, scheme: {args.scheme}, particle order: "
          f"{args.particle_order}, best of "
          f"{args.repeat}; each size in a "
          "fresh process")
    print()

    results: dict = {"machine": info, "scheme": args.scheme,
                     "particle_order": args.particle_order, "repeat": args.repeat,
                     "sizes": [], "fits": {}}
    header = (f"{'dim':>3} {'N':>9} {'pairs/i':>7} {'rates s':>9} {'pairs/s':>9} "
              f"{'1-thr x':>7} {'rebuild s':>9} {'step s':>9} {'step/2r':>7} {'B/part':>7} "
              f"{'RSS MiB':>8}")
    print(header)
    print("-" * len(header))
    for dim in args.dims:
        rows = []
        for n in sizes:
            r = in_child("size", n, dim, args.repeat)
            rows.append(r)
            results["sizes"].append(r)
            print(f"{dim:>3} {r['n_particles']:>9} {r['pairs_per_particle']:>7.2f} "
                  f"{_si(r['rate_seconds']):>9} {_si(r['pair_evaluations_per_second']):>9} "
                  f"{r['parallel_speedup']:>7.2f} "
                  f"{_si(r['neighbour_rebuild_seconds']):>9} {_si(r['step_seconds']):>9} "
                  f"{r['step_over_two_rates']:>7.2f} {r['bytes_per_particle']:>7.0f} "
                  f"{r['peak_rss_mib']:>8.0f}", flush=True)
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
    print("pairs/i: pair evaluations per particle per rate evaluation (|r_ij| < 2h); rates s: "
          "one rate evaluation")
    print("(neighbour update check + passes); pairs/s: pair evaluations per second; 1-thr x: "
          "one-thread time / all-thread")
    print("time; rebuild s: NeighbourList.build(x, 2h, 0.2h); step s: one midpoint step; "
          "step/2r: step / (2 rates s);")
    print("B/part: growth of peak RSS while the lattice was built and run, per particle; RSS: "
          "peak resident set of the process.")

    results["examples"] = []
    if args.examples:
        print()
        print(f"{'example':>10} {'dim':>3} {'N':>6} {'steps':>7} {'wall s':>8} {'us/step':>8} "
              f"{'pairs/s':>9} {'setup s':>7}")
    for name in args.examples:
        b = in_child("example", name)
        results["examples"].append(b)
        print(f"{name:>10} {b['dimension']:>3} {b['n_particles']:>6} {b['n_steps']:>7} "
              f"{b['wall_seconds']:>8.2f} {b['seconds_per_step'] * 1e6:>8.0f} "
              f"{_si(b['pair_evaluations_per_second']):>9} {b['setup_seconds']:>7.2f}",
              flush=True)

    results["skins"] = []
    if args.skins:
        print()
        print("taylor with other neighbour skins (default 0.1 of the support 2h):")
        print(f"{'skin':>6} {'builds':>7} {'wall s':>8} {'us/step':>8} {'vs 0.1':>7}")
    for skin in args.skins:
        b = in_child("example", "taylor", f"time.neighbour_skin={skin}")
        b["skin"] = skin
        results["skins"].append(b)
    default = next((b for b in results["skins"] if b["skin"] == 0.1), None)
    for b in results["skins"]:
        ratio = b["wall_seconds"] / default["wall_seconds"] if default else float("nan")
        print(f"{b['skin']:>6.2f} {b['neighbour_list_builds']:>7} {b['wall_seconds']:>8.2f} "
              f"{b['seconds_per_step'] * 1e6:>8.0f} {ratio:>7.2f}")

    if not args.no_compile:
        with tempfile.TemporaryDirectory() as cache:
            cold = in_child("compile", env={"NUMBA_CACHE_DIR": cache})
            warm = in_child("compile", env={"NUMBA_CACHE_DIR": cache})
        results["compile"] = {"cold": cold, "warm": warm}
        print()
        print("time to a first step (AC, a wall) in a new process, s:   "
              + "   ".join(f"{d}D {cold[f'{d}d_seconds']:.1f} (cached {warm[f'{d}d_seconds']:.1f})"
                           for d in (1, 2, 3)))
        print("(empty numba cache: the one-time compilation; cached: loading the compiled "
              "code from disk)")

    results["peak_rss_mib"] = peak_rss_mib()
    total = results["total_seconds"] = time.perf_counter() - start
    busy1 = cpu_busy_seconds()
    others = (None if busy0 is None or busy1 is None else
              max(0.0, (busy1 - busy0) - (own_cpu_seconds() - own0)) / total)
    results["other_load_during_run"] = others
    print(f"\ntotal {total:.1f} s"
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
