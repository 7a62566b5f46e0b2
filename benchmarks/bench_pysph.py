"""impactsph against PySPH 1.0b2 on PySPH's Taylor bar example, in one session on one machine.

PySPH's ``pysph/examples/solid_mech/taylor_bar.py``: a plane-strain iron bar of 21 x 67 = 1407
particles (dx = 0.384848 mm) at -200 m/s onto a row of 80 fixed plate particles (1487 in
all), Wendland quintic kernel with h = 2 dx (support 2h = 4 dx), dt = 1 ns, 25,000 steps of
its PEC integrator.  The script

1. installs PySPH into its own virtualenv (``--pysph-venv``, default ``.cache/pysph-venv``
   under the repository root) with ``pip install pysph==1.0b2``, unless it is already there;
   if that fails it prints why (the tail of pip's output) and runs the impactsph half only;
2. runs PySPH's example for ``--steps`` steps (output off), timing ``Application.solve()``
   apart from the set-up (which compiles the generated Cython code), and counts the
   neighbour pairs its loops visit from the particle positions every few hundred steps;
3. runs impactsph on the same bar (the same positions, read from a particle file), the same
   support (cubic spline with h = 4 dx / 2, so 2h = 4 dx: the same neighbours), material
   constants as close as impactsph takes them, a ghost-particle wall for the plate, and
   exactly ``--steps`` midpoint steps of 1 ns (``sim.integrator.step(state, 1e-9)``);

each run in a fresh process, one after the other (never two at once), for every thread
count of ``--threads`` (1: PySPH without OpenMP; more: PySPH's ``--openmp`` with
``OMP_NUM_THREADS``, impactsph with ``NUMBA_NUM_THREADS``), ``--repeat`` times each
(alternating the codes; the fastest run of each is kept: other processes on the machine only
ever slow a run down, and the load they put on it during each run is reported).  It prints
a table and the ratios impactsph / PySPH of wall time and of pair evaluations per second;
``--json PATH`` writes everything.

A *pair evaluation* is one ordered pair (i, j), i != j, with |x_i - x_j| < support visited
by one neighbour sweep.  impactsph makes one sweep per rate evaluation, two rate evaluations
per step (``solver.pair_evaluations``, exact).  PySPH's PEC integrator makes one
acceleration evaluation per step (plus one before the first step); it has two equation
groups that loop over neighbours, so each evaluation sweeps the bar's neighbours of the bar
twice (group 1: velocity gradient; group 2: continuity, momentum, viscosity, energy and
XSPH in one loop) and the plate neighbours of the bar once (boundary force, group 2).  The
main count takes all three sweeps; the JSON also gives the count with one sweep per
evaluation.  See benchmarks/PYSPH.md.

Usage::

    python benchmarks/bench_pysph.py                       # 1 thread, 25,000 steps
    python benchmarks/bench_pysph.py --threads 1 2 --repeat 2 --json pysph.json
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
PYSPH_VERSION = "1.0b2"
# pip's requirements for the PySPH virtualenv.  No pins beyond PySPH itself: 1.0b2 builds
# (gcc, pip's build isolation) and runs with what pip resolves today (numpy 2.4, Cython 3.3,
# compyle 0.9.1, cyarray 1.2 on Python 3.11, tried 2026-11); the versions actually installed
# are recorded in the output.
PYSPH_REQUIREMENTS = [f"pysph=={PYSPH_VERSION}"]

# PySPH's example (pysph/examples/solid_mech/taylor_bar.py), its constants in SI units
DX = 0.000384848  # m, particle spacing (dx = dy)
HDX = 2.0  # h / dx of the Wendland quintic
RADIUS_SCALE = 2.0  # the Wendland quintic's support in units of h
SUPPORT = RADIUS_SCALE * HDX * DX  # 4 dx
BAR_WIDTH = 0.0076  # m
BAR_LENGTH = 0.0254  # m
RHO0 = 7850.0  # kg/m^3
SOUND_SPEED = 4699.0  # m/s, the constant cs of the viscosity (and the boundary force)
# its Mie-Gruneisen constants.  The (dimensionless) slope S = 1800 looks like a slip for 1.8
# (iron); impactsph is given the same 1800 so that both codes solve the same equations (with
# 1.8 the impactsph bar ends at 0.862 of its height at 25 us instead of 0.865)
MG_C, MG_S, MG_GAMMA = 3630.0, 1800.0, 1.81
SHEAR = 8e10  # Pa
YIELD = 6e8  # Pa
AV_ALPHA, AV_BETA, AV_EPS = 0.5, 0.5, 0.01  # Monaghan viscosity, eps h^2 in the denominator
VELOCITY = -200.0  # m/s, along y
DT = 1e-9  # s
# impactsph's wall plane: the bar's bottom row (y = 4 dx) lies dx/2 above it, as impactsph puts
# a lattice on a wall; PySPH's plate row lies at y = 0 and its boundary force reaches 4 dx, so
# in both codes the wall acts on the bottom row from the first step.
WALL_Y = 3.5 * DX
#: issue 16: impactsph's pair evaluations per second over PySPH's, on its Taylor bar
PAIRS_TARGET = 4.0


def pysph_bar_positions() -> np.ndarray:
    """The bar's particles as PySPH's example places them (its ``get_bar_particles``)."""
    xarr = np.arange(-BAR_WIDTH / 2.0, BAR_WIDTH / 2.0 + DX, DX)
    yarr = np.arange(4 * DX, BAR_LENGTH + 4 * DX, DX)
    x, y = np.meshgrid(xarr, yarr)
    return np.stack([x.ravel(), y.ravel()], axis=1)


def ordered_pairs(a: np.ndarray, b: np.ndarray | None, radius: float) -> int:
    """Ordered pairs (i in a, j in b) with |a_i - b_j| < radius; with ``b`` None, pairs of
    ``a`` with itself, i != j."""
    other = a if b is None else b
    d2 = np.zeros((a.shape[0], other.shape[0]))
    for k in range(a.shape[1]):
        d2 += np.subtract.outer(a[:, k], other[:, k]) ** 2
    count = int(np.count_nonzero(d2 < radius * radius))
    return count - a.shape[0] if b is None else count


def time_average(step: np.ndarray, value: np.ndarray) -> float:
    """Trapezoidal mean of ``value`` sampled at ``step`` over the steps sampled."""
    if step[-1] == step[0]:
        return float(value.mean())
    area = np.sum(0.5 * (value[1:] + value[:-1]) * np.diff(step))
    return float(area / (step[-1] - step[0]))


def bar_height(y: np.ndarray) -> float:
    return float(y.max() - y.min())


# -- the PySPH worker (runs in the PySPH virtualenv: standard library and numpy only) ----------


def pysph_worker(steps: int, threads: int, sample_every: int, workdir: str) -> dict:
    """Run PySPH's Taylor bar for ``steps`` steps; returns the timings and pair counts."""
    import pysph
    from pysph.examples.solid_mech import taylor_bar

    assert taylor_bar.dx == DX and taylor_bar.hdx == HDX and taylor_bar.r0 == RHO0
    app = taylor_bar.TaylorBar(fname="taylor_bar", output_dir=workdir)
    argv = ["--max-steps", str(steps), "--tf", repr((steps + 0.5) * DT), "--disable-output",
            "-q", "-d", workdir, "--openmp" if threads > 1 else "--no-openmp"]
    t0 = time.perf_counter()
    app.setup(argv)  # builds the particles and compiles (or loads) the generated extension
    setup = time.perf_counter() - t0
    solver = app.solver
    arrays = {pa.name: pa for pa in app.particles}
    bar, plate = arrays["bar"], arrays["plate"]
    assert solver.kernel.radius_scale == RADIUS_SCALE and solver.dt == DT
    assert np.allclose(bar.h, HDX * DX) and not plate.h.any()  # the support is the bar's 2h
    plate_xy = np.stack([plate.x, plate.y], axis=1)
    x0 = np.stack([bar.x, bar.y], axis=1).copy()
    samples: list[tuple[int, int, int]] = []
    overhead = [0.0, 0.0]  # wall and CPU seconds spent counting pairs

    def sample() -> None:
        t, c = time.perf_counter(), time.process_time()
        xy = np.stack([bar.x, bar.y], axis=1)
        # PySPH's neighbour test: |r_ij|^2 < (2 max(h_i, h_j))^2; the plate's h is 0
        samples.append((solver.count, ordered_pairs(xy, None, SUPPORT),
                        ordered_pairs(xy, plate_xy, SUPPORT)))
        overhead[0] += time.perf_counter() - t
        overhead[1] += time.process_time() - c

    def post_step(_solver) -> None:
        if solver.count % sample_every == 0 or solver.count == steps:
            sample()

    sample()
    solver.add_post_step_callback(post_step)
    t0, c0 = time.perf_counter(), time.process_time()
    app.solve()  # initial acceleration evaluation + the steps
    wall = time.perf_counter() - t0 - overhead[0]
    cpu = time.process_time() - c0 - overhead[1]
    counts = np.array(samples, dtype=float)
    bb, bp = time_average(counts[:, 0], counts[:, 1]), time_average(counts[:, 0], counts[:, 2])
    evaluations = solver.count + 1  # PEC: one per step, plus the initial one
    sweeps_per_evaluation = 2 * bb + bp
    xy = np.stack([bar.x, bar.y, bar.u, bar.v], axis=1)
    return {
        "code": "pysph", "version": pysph.__version__, "threads": threads,
        "openmp": threads > 1, "particles": int(bar.get_number_of_particles()
                                                 + plate.get_number_of_particles()),
        "integrated_particles": int(bar.get_number_of_particles()),
        "wall_particles": int(plate.get_number_of_particles()),
        "steps": int(solver.count), "dt": float(solver.t / solver.count), "t_end": float(solver.t),
        "setup_seconds": setup, "wall_seconds": wall, "cpu_seconds": cpu,
        "sampling_seconds": overhead[0],
        "acceleration_evaluations": evaluations,
        "bar_bar_pairs_mean": bb, "bar_plate_pairs_mean": bp,
        "bar_bar_pairs_first_last": [int(counts[0, 1]), int(counts[-1, 1])],
        "pair_samples": len(samples),
        "pair_evaluations": sweeps_per_evaluation * evaluations,
        "pair_evaluations_one_sweep_per_evaluation": (bb + bp) * evaluations,
        "finite": bool(np.isfinite(xy).all()),
        "bar_height_initial": bar_height(x0[:, 1]), "bar_height_final": bar_height(bar.y),
        "initial_positions": x0.tolist(),
    }


# -- the impactsph worker ---------------------------------------------------------------------


def impactsph_case(particle_file: str, steps: int) -> dict:
    """The Taylor bar of PySPH's example as an impactsph case dict."""
    youngs = RHO0 * SOUND_SPEED**2  # so that the bar wave speed sqrt(E/rho0) is PySPH's cs
    return {
        "name": "pysph_taylor_bar",
        "dimension": 2,
        "materials": {"iron": {
            "model": "elastic_plastic", "density": RHO0, "youngs_modulus": youngs,
            "shear_modulus": SHEAR, "poisson_ratio": youngs / (2.0 * SHEAR) - 1.0,
            "eos": "mie_gruneisen", "yield_stress": YIELD,
            "mie_gruneisen": {"sound_speed": MG_C, "slope": MG_S,
                              "gamma": MG_GAMMA}}},
        "bodies": [{"name": "bar", "material": "iron", "velocity": [0.0, VELOCITY],
                    "geometry": {"type": "file", "path": particle_file, "spacing": DX}}],
        "boundaries": [{"type": "wall", "point": [0.0, WALL_Y], "normal": [0.0, 1.0],
                        "slip": "free"}],
        # impactsph's cubic spline reaches 2h: h = SUPPORT / 2 = 2 dx, PySPH's 2h = 4 dx
        "kernel": {"h_over_dx": SUPPORT / 2.0 / DX},
        "viscosity": {"scheme": "av", "alpha1": AV_ALPHA, "alpha2": AV_BETA,
                      "epsilon": AV_EPS},
        "time": {"end": steps * DT, "max_steps": steps, "wave_speed": "bar"},
        "output": {"figures": False},
    }


def impactsph_worker(steps: int, threads: int) -> dict:
    """Run the impactsph Taylor bar for exactly ``steps`` steps of ``DT``."""
    import numba

    import impactsph
    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    x0 = pysph_bar_positions()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bar.npz")
        np.savez(path, position=x0, volume=np.full(x0.shape[0], DX * DX))
        case = validate_case(impactsph_case(path, steps))
        warm = Simulation(case)  # compiles (or loads) the rate kernels
        warm.integrator.step(warm.state, DT)  # ... and the integrator's
        del warm
        sim = Simulation(case)
    setup = time.perf_counter() - t0
    state, solver = sim.state, sim.solver
    solver.pair_evaluations = solver.rate_evaluations = 0
    builds0 = solver.neighbours.builds
    ghosts0 = solver.buffers.drho.shape[0] - state.n
    step = sim.integrator.step
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        step(state, DT)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    finite = all(bool(np.isfinite(getattr(state, f)).all())
                 for f in ("position", "velocity", "density", "deviatoric_stress"))
    return {
        "code": "impactsph", "version": impactsph.__version__, "threads": threads,
        "source": os.path.dirname(impactsph.__file__),
        "numba_threads": numba.get_num_threads(),
        "particles": state.n, "integrated_particles": state.n,
        "wall_ghosts_first_last": [ghosts0, solver.buffers.drho.shape[0] - state.n],
        "steps": state.step, "dt": DT, "t_end": state.time,
        "setup_seconds": setup, "wall_seconds": wall, "cpu_seconds": cpu,
        "rate_evaluations": solver.rate_evaluations,
        "pair_evaluations": solver.pair_evaluations,
        "neighbour_list_builds": solver.neighbours.builds - builds0,
        "finite": finite,
        "bar_height_initial": bar_height(x0[:, 1]),
        "bar_height_final": bar_height(state.position[:, 1]),
    }


# -- the driver -------------------------------------------------------------------------------


def children_cpu_seconds() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_worker(python: str, args: list[str], threads: int, timeout: float) -> dict:
    """Run this script as a worker in a fresh process; returns its result (the last line of
    its output, JSON) with the load the other processes put on the machine meanwhile."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), NUMBA_NUM_THREADS=str(threads))
    if args[1] == "pysph":  # the PySPH virtualenv sees nothing of this one
        env.pop("PYTHONPATH", None)
    from bench_rates import cpu_busy_seconds  # this script's folder; the driver's venv

    busy0, own0, t0 = cpu_busy_seconds(), children_cpu_seconds(), time.perf_counter()
    proc = subprocess.run([python, str(Path(__file__).resolve()), *args], env=env,
                          capture_output=True, text=True, timeout=timeout, cwd=REPO)
    elapsed = time.perf_counter() - t0
    busy1, own1 = cpu_busy_seconds(), children_cpu_seconds()
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines or not lines[-1].startswith("{"):
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-25:])
        raise RuntimeError(f"worker {' '.join(args)} failed (exit {proc.returncode}):\n{tail}")
    result = json.loads(lines[-1])
    result["process_seconds"] = elapsed
    result["other_load"] = (None if busy0 is None or busy1 is None else
                            max(0.0, (busy1 - busy0) - (own1 - own0)) / elapsed)
    return result


def venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


def pysph_installed(venv: Path) -> dict | None:
    """Versions in the PySPH virtualenv if PySPH ``PYSPH_VERSION`` imports there, else None."""
    python = venv_python(venv)
    if not python.exists():
        return None
    code = ("import json, pysph, numpy, Cython, compyle, cyarray, mako; "
            "print(json.dumps({'pysph': pysph.__version__, 'numpy': numpy.__version__, "
            "'cython': Cython.__version__, 'compyle': compyle.__version__, "
            "'cyarray': getattr(cyarray, '__version__', '?'), 'mako': mako.__version__}))")
    proc = subprocess.run([str(python), "-c", code], capture_output=True, text=True,
                          timeout=120)
    if proc.returncode != 0:
        return None
    versions = json.loads(proc.stdout.strip().splitlines()[-1])
    return versions if versions["pysph"] == PYSPH_VERSION else None


def install_pysph(venv: Path) -> dict:
    """Make sure PySPH ``PYSPH_VERSION`` is installed in ``venv``; returns what happened."""
    versions = pysph_installed(venv)
    if versions is not None:
        return {"ok": True, "installed_now": False, "venv": str(venv), "versions": versions}
    print(f"installing PySPH {PYSPH_VERSION} into {venv} (pip builds its Cython extensions; "
          "a few minutes)...", flush=True)
    t0 = time.perf_counter()
    log: list[str] = []
    try:
        if venv.exists():
            shutil.rmtree(venv)
        venv.parent.mkdir(parents=True, exist_ok=True)
        # the virtualenv takes the base interpreter of the one running this script
        base = getattr(sys, "_base_executable", None) or sys.executable
        commands = [[base, "-m", "venv", str(venv)],
                    [str(venv_python(venv)), "-m", "pip", "install", *PYSPH_REQUIREMENTS]]
        env = dict(os.environ)
        env.pop("PYTHONPATH", None)
        for cmd in commands:
            log.append("$ " + " ".join(cmd))
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=3600, env=env)
            log.extend((proc.stdout + proc.stderr).splitlines())
            if proc.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd[-3:])} exited with {proc.returncode}")
        versions = pysph_installed(venv)
        if versions is None:
            raise RuntimeError("pip succeeded but 'import pysph' fails in the virtualenv")
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        tail = "\n".join(log[-30:])
        return {"ok": False, "venv": str(venv), "error": str(exc), "pip_tail": tail,
                "seconds": time.perf_counter() - t0}
    return {"ok": True, "installed_now": True, "venv": str(venv), "versions": versions,
            "seconds": time.perf_counter() - t0, "commands": [" ".join(c) for c in commands]}


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def git_commit(where: str) -> str:
    """Commit of the git checkout holding ``where``, ``+dirty`` if files under it differ."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=where,
                                capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                "."], cwd=where, capture_output=True, text=True,
                               timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "") if commit else "not a git checkout"


def machine_info() -> dict:
    import numba

    import impactsph

    try:
        gcc = subprocess.run(["gcc", "--version"], capture_output=True, text=True,
                             timeout=10).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        gcc = "not found"
    source = os.path.dirname(os.path.abspath(impactsph.__file__))
    return {"date": _dt.datetime.now().isoformat(timespec="seconds"),
            "impactsph_source": source, "git_commit": git_commit(source),
            "impactsph": impactsph.__version__,
            "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "gcc": gcc, "cpu": cpu_model(),
            "cpu_count": os.cpu_count(), "platform": platform.platform()}


def per_step(r: dict) -> None:
    r["us_per_step"] = r["wall_seconds"] / r["steps"] * 1e6
    r["pair_evaluations_per_step"] = r["pair_evaluations"] / r["steps"]
    r["pair_evaluations_per_second"] = r["pair_evaluations"] / r["wall_seconds"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=25000, help="time steps (default 25000)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1],
                    help="thread counts to compare (default: 1)")
    ap.add_argument("--skip-pysph", action="store_true", help="run the impactsph half only")
    ap.add_argument("--pysph-venv", type=Path, default=REPO / ".cache" / "pysph-venv",
                    help="virtualenv for PySPH (default: .cache/pysph-venv)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of each code and thread count, alternating; the fastest is "
                         "kept (default 1)")
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument("--worker", choices=("pysph", "impactsph"), help=argparse.SUPPRESS)
    ap.add_argument("--worker-threads", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--workdir", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.steps < 1 or min(args.threads) < 1 or args.repeat < 1:
        ap.error("--steps, --threads and --repeat must be >= 1")

    if args.worker == "pysph":
        every = max(1, args.steps // 50)
        print(json.dumps(pysph_worker(args.steps, args.worker_threads, every, args.workdir)))
        return 0
    if args.worker == "impactsph":
        print(json.dumps(impactsph_worker(args.steps, args.worker_threads)))
        return 0

    info = machine_info()
    print(f"impactsph vs PySPH {PYSPH_VERSION}: PySPH's Taylor bar example  {info['date']}")
    print(f"impactsph {info['impactsph']} ({info['git_commit']}: {info['impactsph_source']})")
    print(f"python {info['python']}  numpy {info['numpy']}  numba {info['numba']}")
    print(f"CPU: {info['cpu']} x {info['cpu_count']}   {info['gcc']}")
    pysph: dict = {"ok": False, "error": "skipped (--skip-pysph)"}
    if not args.skip_pysph:
        venv = args.pysph_venv.expanduser().resolve()
        pysph = install_pysph(venv)
        if pysph["ok"]:
            v = pysph["versions"]
            how = (f"installed now in {pysph['seconds']:.0f} s" if pysph["installed_now"]
                   else "already installed")
            print(f"PySPH {v['pysph']} ({how}, {venv}): numpy {v['numpy']}  Cython "
                  f"{v['cython']}  compyle {v['compyle']}  cyarray {v['cyarray']}")
        else:
            print(f"PySPH could not be installed: {pysph['error']}\n--- pip output "
                  f"(tail) ---\n{pysph['pip_tail']}\n---\nrunning the impactsph half only")
    print(f"{args.steps} steps of {DT:g} s; dx = {DX * 1e3:.6f} mm, support {SUPPORT / DX:g} dx "
          f"= {SUPPORT * 1e3:.4f} mm; fastest of {args.repeat} run(s) each", flush=True)

    attempts: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for threads in args.threads:
            timeout = 600 + 0.1 * args.steps * (2 if threads == 1 else 1)
            for attempt in range(args.repeat):
                if pysph["ok"]:
                    try:
                        r = run_worker(str(venv_python(Path(pysph["venv"]))),
                                       ["--worker", "pysph", "--worker-threads", str(threads),
                                        "--steps", str(args.steps), "--workdir",
                                        os.path.join(tmp, f"pysph-{threads}-{attempt}")],
                                       threads, timeout)
                    except (RuntimeError, subprocess.SubprocessError) as exc:
                        pysph.update(ok=False, error=f"PySPH run failed: {exc}")
                        print(f"{pysph['error']}\nrunning the impactsph half only", flush=True)
                if pysph["ok"]:
                    x0 = np.array(r.pop("initial_positions"))
                    same = x0.shape == pysph_bar_positions().shape
                    r["same_positions_as_impactsph"] = bool(
                        same and np.array_equal(x0, pysph_bar_positions()))
                    per_step(r)
                    attempts.append(r)
                    print(f"  PySPH     {threads} thread(s): {r['wall_seconds']:.1f} s "
                          f"(other load {r['other_load'] or 0:.2f})", flush=True)
                r = run_worker(sys.executable, ["--worker", "impactsph", "--worker-threads",
                                                str(threads), "--steps", str(args.steps)],
                               threads, timeout)
                per_step(r)
                attempts.append(r)
                print(f"  impactsph {threads} thread(s): {r['wall_seconds']:.1f} s "
                      f"(other load {r['other_load'] or 0:.2f})", flush=True)
    # the fastest of the attempts of each code and thread count
    runs = []
    for threads in args.threads:
        for code in ("pysph", "impactsph"):
            mine = [r for r in attempts if r["code"] == code and r["threads"] == threads]
            if mine:
                runs.append(min(mine, key=lambda r: r["wall_seconds"]))

    print()
    header = (f"{'code':<10} {'threads':>7} {'particles':>9} {'steps':>6} {'wall s':>8} "
              f"{'cpu s':>8} {'us/step':>8} {'pairs/step':>10} {'pairs/s':>9} {'setup s':>7} "
              f"{'L/L0':>6} {'other':>5}")
    print(header)
    print("-" * len(header))
    for r in runs:
        load = "" if r["other_load"] is None else f"{r['other_load']:.2f}"
        print(f"{r['code']:<10} {r['threads']:>7} {r['particles']:>9} {r['steps']:>6} "
              f"{r['wall_seconds']:>8.2f} {r['cpu_seconds']:>8.2f} {r['us_per_step']:>8.1f} "
              f"{r['pair_evaluations_per_step']:>10.4g} "
              f"{r['pair_evaluations_per_second']:>9.3g} {r['setup_seconds']:>7.1f} "
              f"{r['bar_height_final'] / r['bar_height_initial']:>6.3f} {load:>5}")
    ratios = []
    for threads in args.threads:
        mine = [r for r in runs if r["threads"] == threads]
        if len(mine) == 2:
            p, i = mine
            ratio = {"threads": threads,
                     "wall_time_impactsph_over_pysph": i["wall_seconds"] / p["wall_seconds"],
                     "cpu_time_impactsph_over_pysph": i["cpu_seconds"] / p["cpu_seconds"],
                     "pairs_per_second_impactsph_over_pysph":
                         i["pair_evaluations_per_second"] / p["pair_evaluations_per_second"],
                     "pairs_per_second_ratio_one_sweep_per_evaluation":
                         i["pair_evaluations_per_second"] / (
                             p["pair_evaluations_one_sweep_per_evaluation"]
                             / p["wall_seconds"])}
            ratios.append(ratio)
    print()
    print("particles: PySPH 1407 bar + 80 plate (the plate is not integrated); impactsph "
          "1407 bar + wall ghosts")
    print("pairs: ordered pairs i != j closer than the support (4 dx), per neighbour sweep; "
          "PySPH 3 sweeps per step")
    print("(bar-bar twice, bar-plate once), impactsph 2 (one per rate evaluation); L/L0: bar "
          "height at the end / at t = 0;")
    print("cpu s: CPU time of the timed part (all threads); other: cores kept busy by other "
          "processes during the run")
    for ratio in ratios:
        met = ratio["pairs_per_second_impactsph_over_pysph"] >= PAIRS_TARGET
        print(f"{ratio['threads']} thread(s): impactsph / PySPH wall time "
              f"{ratio['wall_time_impactsph_over_pysph']:.3f} (CPU time "
              f"{ratio['cpu_time_impactsph_over_pysph']:.3f}); pairs/s "
              f"{ratio['pairs_per_second_impactsph_over_pysph']:.3f} "
              f"({ratio['pairs_per_second_ratio_one_sweep_per_evaluation']:.3f} counting "
              f"PySPH's one sweep per evaluation); issue 16's target pairs/s >= "
              f"{PAIRS_TARGET:g}: "
              f"{'met' if met else 'not met'}")
    for r in runs:
        if not r["finite"]:
            print(f"WARNING: {r['code']} ({r['threads']} threads) ended with non-finite values")
        if r["other_load"] is not None and r["other_load"] > 0.2:
            print(f"WARNING: other processes kept {r['other_load']:.2f} cores busy during "
                  f"the {r['code']} run ({r['threads']} threads); its timing is suspect")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": info, "steps": args.steps, "dt": DT, "pysph_install": pysph,
                       "repeat": args.repeat, "runs": runs, "ratios": ratios,
                       "attempts": attempts}, fh, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
