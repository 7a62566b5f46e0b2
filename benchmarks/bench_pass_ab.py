"""One compiled neighbour pass of this tree against the same pass generated from another
source tree's template, in one process, on the same captured inputs, alternated call by call
in rounds; and the largest relative difference of each output.

    .venv/bin/python benchmarks/bench_pass_ab.py /tmp/old [--cases 2d 3d taylor]
        [--passes pair_pass] [--n 1e5] [--rounds 8] [--json ab.json]

Separate processes per tree (``bench_passes.py --trees``) see this machine's spells, in which
the same pass takes 1.5-2x as long for minutes at a time, as differences between the trees;
here both passes share every spell.  The other tree's generated module is written by that
tree (a worker with ``TREE/src`` as its impactsph, which compiles nothing) for the options of
the run here (dimension, scheme, stabilisation, one smoothing length or not, serial or
threaded by the numba thread count), and compiled here with this tree's models and helpers:
so it compares the templates (``physics/passes.py``), not a change to a helper it imports or
to a registered model.

Cases: ``2d`` and ``3d`` are ``bench_rates.py``'s lattices (the paper's scheme, AV, h = 1.2 dx,
random velocities of about 1 m/s), ``2dstab`` and ``3dstab`` the same with an elastic case's
stabilisation (the kernel gradient correction of the velocity gradient and the forces, the
hourglass control); ``taylor``, ``cantilever`` and ``bars`` the built-in cases after 2 us.
Passes: those of the module of the run's neighbour loops (``CpuRates.neighbour_loops``):
``moment_pass``, ``gradient_pass``, ``pair_pass``, ``hourglass_pass`` (a pass the case does not
run is left out); and ``stage``, the integrator's stage from the module of the run's stage
options (``MidpointIntegrator.stage_options``), on the inputs of the run's next predictor
stage (the start copy made, the update, the return map, the walls), its arrays restored
before every timed call (a stage writes the state it reads).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _trees import worker_result  # noqa: E402

CASES = ("2d", "3d", "2dstab", "3dstab", "taylor", "cantilever", "bars")
PASSES = ("moment_pass", "gradient_pass", "pair_pass", "hourglass_pass", "stage")
STABILISATION = {"gradient_correction": "velocity_gradient_and_forces", "hourglass": 2.0}


def build(case: str, n: int):
    """The case's simulation, built (nothing compiled or run)."""
    from impactsph import Simulation, load_case
    from impactsph.loading import validate_case

    if case in ("2d", "3d", "2dstab", "3dstab"):
        from bench_rates import make_case

        spec = make_case(n, int(case[0]))
        if case.endswith("stab"):
            spec.setdefault("stabilisation", {}).update(STABILISATION)
        sim = Simulation(validate_case(spec))
        rng = np.random.default_rng(1)
        sim.state.velocity[:] = rng.normal(size=sim.state.velocity.shape)
        return sim
    return Simulation(load_case(case, ["output.figures=false"]))


def simulation(case: str, n: int):
    """The case's simulation, ready for a rate evaluation (a built-in case after 2 us)."""
    sim = build(case, n)
    if case in ("taylor", "cantilever", "bars"):
        sim.run(2e-6)
    return sim


def loops_options(sim, uniform_h: bool):
    """The compile-time options of the run's neighbour-loop module."""
    from dataclasses import replace

    options = sim.solver.backend.options
    return (replace(options, uniform_h=True) if uniform_h else options).compiled()


def worker(case: str, n: int, uniform_h: bool) -> dict[str, Any]:
    """In the other tree: the text of the generated module that the run's neighbour loops
    would use (nothing compiled)."""
    from impactsph import codegen
    from impactsph.physics import passes

    sim = build(case, n)
    options = loops_options(sim, uniform_h)
    text, _ = codegen.generate(passes, sim.solver.backend.dim, options)
    result = {"text": text, "tag": options.tag}
    stage = getattr(sim.integrator, "stage_options", None)  # (a tree before 2026-12-06: none)
    if stage is not None:
        result["stage_text"], _ = codegen.generate(passes, sim.solver.backend.dim, stage)
        result["stage_tag"] = stage.tag
    return result


def chunked(function: Any) -> bool:
    """Whether a pass takes ``(first, step, ...)`` (:mod:`impactsph.physics.chunked`, since
    2026-12-05; a tree before then has ``prange`` passes without them)."""
    return getattr(function, "py_func", function).__code__.co_varnames[:2] == ("first", "step")


def caller(module, name: str) -> Any:
    """A call of ``module``'s pass ``name`` on its arguments without ``first, step``, over
    every chunk on numba's thread count: a chunked pass through
    :func:`impactsph.physics.chunked.run_chunked`, a ``prange`` one as it is."""
    import functools

    import numba

    from impactsph.physics.chunked import run_chunked

    function = getattr(module, name)
    if chunked(function):
        return functools.partial(run_chunked, function, numba.get_num_threads())
    return function


def captured_inputs(sim, name: str) -> tuple[Any, list[Any] | None]:
    """The run's neighbour-loop module and the arguments of its pass ``name`` in one rate
    evaluation (None if the evaluation does not call it), without a chunked pass's ``first,
    step``."""
    sim.solver.rates(sim.state)
    module = sim.solver.backend._loops
    function, captured = getattr(module, name), {}
    skip = 2 if chunked(function) else 0

    def capture(*args):
        if not skip or args[0] == 0:  # (the call of the first thread)
            captured["args"] = [a.copy() if isinstance(a, np.ndarray) else a
                                for a in args[skip:]]
        return function(*args)

    # the rate buffers emptied (NaN) first, so that what the pass writes shows
    for buffer in [*vars(sim.solver.buffers).values(), sim.solver.backend._gradients]:
        if isinstance(buffer, np.ndarray) and buffer.dtype.kind == "f":
            buffer.fill(np.nan)
    setattr(module, name, capture)
    try:
        sim.solver.rates(sim.state)
    finally:
        setattr(module, name, function)
    return module, captured.get("args")


def captured_stage(sim) -> tuple[Any, list[Any]]:
    """The run's stage module and the arguments of its next predictor stage (the step's
    first, which makes the start copy), without ``first, step``."""
    from impactsph.physics.rates import compiled_passes

    it = sim.integrator
    function, captured = it._stage_pass, {}

    def capture(*args):  # (no numba dispatcher: run_chunked calls it for each share)
        if args[0] == 0 and "args" not in captured:  # (the predictor's, not the corrector's)
            captured["args"] = [a.copy() if isinstance(a, np.ndarray) else a
                                for a in args[2:]]
        return function(*args)

    it._stage_pass = capture
    try:
        it.step(sim.state, sim._survey().dt)  # (the run's own step)
    finally:
        it._stage_pass = function
    return compiled_passes(sim.state.dim, options=it.stage_options), captured["args"]


def load_other(text: str, sim, uniform_h: bool, directory: Path, tag: str,
               options: Any = None):
    """The other tree's module text compiled here, with this tree's models injected (for
    the run's neighbour loops' options, or ``options``)."""
    from impactsph import codegen
    from impactsph.physics import passes

    options = loops_options(sim, uniform_h) if options is None else options
    _, inject = codegen.generate(passes, sim.solver.backend.dim, options)
    # named as codegen names its modules (whose serial ones' warning it silences)
    key = hashlib.sha256(text.encode()).hexdigest()[:16]
    stem = f"other_passes_{sim.solver.backend.dim}d{tag}_{key}"
    path = directory / f"{stem}.py"
    path.write_text(text)
    name = f"impactsph_generated.{stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    module.__dict__.update(inject)
    sys.modules[name] = module
    exec(compile(text, str(path), "exec"), module.__dict__)
    return module


def largest_differences(args: list[Any], here, other, name: str) -> tuple[list[float], int]:
    """The largest difference of each floating-point array after the two modules' passes
    (their inputs' give 0), over its largest magnitude; and how many of them the pass here
    wrote (changed from the captured state)."""
    runs = []
    for module in (here, other):
        run = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
        caller(module, name)(*run)
        runs.append(run)
    diffs, written = [], 0
    for given, a, b in zip(args, *runs, strict=True):
        if not (isinstance(a, np.ndarray) and a.dtype.kind == "f" and a.size):
            continue
        written += not np.array_equal(a, given, equal_nan=True)
        scale = float(np.nanmax(np.abs(b), initial=0.0)) or 1.0
        diffs.append(float(np.nanmax(np.abs(a - b), initial=0.0)) / scale)
    return diffs, written


def best_times(args: list[Any], modules: dict[str, Any], name: str, rounds: int,
               particles: int, restore: bool = False) -> dict[str, list[float]]:
    """Each module's best call of the pass in each round, the modules alternating (with
    ``restore``, every array argument set back to its given values before each call,
    outside the timing)."""
    calls = max(5, int(2e5 // max(particles, 1)))  # some 0.2 s a round at every size
    given = [(a, a.copy()) for a in args if isinstance(a, np.ndarray)] if restore else []
    times: dict[str, list[float]] = {label: [] for label in modules}
    for _ in range(rounds):
        for label, module in modules.items():
            function, best = caller(module, name), np.inf
            for _ in range(calls):
                for array, values in given:
                    np.copyto(array, values)
                t0 = time.perf_counter()
                function(*args)
                best = min(best, time.perf_counter() - t0)
            times[label].append(best)
    for array, values in given:
        np.copyto(array, values)
    return times


def measure(case: str, tree: Path, names: list[str], n: int, rounds: int,
            directory: Path) -> dict[str, Any]:
    """Both trees' passes ``names`` on the case's captured inputs."""
    import numba

    sim = simulation(case, n)
    sim.solver.rates(sim.state)
    here = sim.solver.backend._loops
    uniform_h = bool(sim.solver.backend._uniform is here)
    text = worker_result(__file__, tree, [case, str(n), str(int(uniform_h))],
                         numba.get_num_threads())
    other = load_other(text["text"], sim, uniform_h, directory, text["tag"])
    result: dict[str, Any] = {"particles": int(sim.state.n), "module": Path(here.__file__).name,
                              "passes": {}}
    for name in names:
        if name == "stage":
            if "stage_text" not in text:
                continue  # (the other tree has no stage module of its own)
            module, args = captured_stage(sim)
            against = load_other(text["stage_text"], sim, uniform_h, directory,
                                 text["stage_tag"], sim.integrator.stage_options)
        else:
            (module, args), against = captured_inputs(sim, name), other
        if args is None:
            continue
        differences, written = largest_differences(args, module, against, name)
        times = best_times(args, {"here": module, "other": against}, name, rounds,
                           sim.state.n, restore=name == "stage")
        result["passes"][name] = {**times, "differences": differences, "written": written,
                                  "module": Path(module.__file__).name}
    return result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tree", nargs="?", type=Path, help="the other source tree")
    ap.add_argument("--cases", nargs="+", default=["2d", "3d", "taylor"], choices=CASES)
    ap.add_argument("--passes", nargs="+", default=["pair_pass"], choices=PASSES)
    ap.add_argument("--n", type=float, default=1e5, help="the lattices' particle count")
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--json", type=Path, help="write every number here")
    ap.add_argument("--worker", nargs=3, metavar=("CASE", "N", "UNIFORM_H"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        case, n, uniform = args.worker
        print(json.dumps(worker(case, int(n), uniform == "1")))
        return 0
    if args.tree is None:
        ap.error("the other source tree is needed")
    import numba

    from impactsph import __version__

    print(f"impactsph {__version__} here against {args.tree}; {numba.get_num_threads()} "
          f"thread(s); best call of each round, ms")
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            r = results[case] = measure(case, args.tree, args.passes, int(args.n), args.rounds,
                                        Path(tmp))
            for name, t in r["passes"].items():
                here, other = np.array(t["here"]), np.array(t["other"])
                print(f"{case} ({r['particles']} particles, {t['module']}) {name}")
                print("  here  " + " ".join(f"{x * 1e3:8.3f}" for x in here))
                print("  other " + " ".join(f"{x * 1e3:8.3f}" for x in other))
                print(f"  here / other: best {here.min() / other.min():.3f}, median of the "
                      f"rounds {np.median(here / other):.3f}; largest relative difference of "
                      f"an output {max(t['differences'], default=0.0):.1e}")
    if args.json:
        args.json.write_text(json.dumps({
            "version": __version__, "other": str(args.tree), "machine": platform.platform(),
            "processor": platform.processor(), "threads": numba.get_num_threads(),
            "n": args.n, "rounds": args.rounds, "cases": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
