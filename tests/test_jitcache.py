"""Each dimension's variant of a kernel compiled from one closure has numba cache files of its
own (:mod:`impactsph.jitcache`): with one shared index, two processes compiling two
dimensions at once could leave the index naming the other dimension's code, and the next run
that loaded it crashed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

SCRIPT = r"""
import json, sys
import numpy as np
from impactsph.neighbours import _build_functions
out = {}
for dim in (2, 3):
    x = np.arange(12.0 * dim).reshape(-1, dim) ** 1.5
    ref = (x - 0.25 * np.arange(dim)).astype(np.float32)
    moved = _build_functions(dim)[1]
    value = float(moved(x, ref, np.zeros(dim)))
    out[dim] = [value, sum(moved.stats.cache_hits.values()), sum(moved.stats.cache_misses.values())]
print(json.dumps(out))
"""


def _run(cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_each_dimension_has_its_own_cache_files(tmp_path):
    first = _run(str(tmp_path))
    indexes = sorted(p.name for p in tmp_path.rglob("*max_displacement*.nbi"))
    assert len(indexes) == 2, indexes
    assert any("_2d-" in name for name in indexes) and any("_3d-" in name for name in indexes)
    # the second process loads both variants from the cache, and they compute as compiled
    second = _run(str(tmp_path))
    for dim in ("2", "3"):
        assert first[dim][1:] == [0, 1]
        assert second[dim][1:] == [1, 0]
        assert second[dim][0] == first[dim][0]
    assert first["2"][0] != first["3"][0]


RACE = r"""
import sys, time
lock = sys.argv[4] == "lock"
if lock:
    import impactsph  # noqa: F401  (installs the lock)
else:  # numba's own save: the lock's effect shown by its absence
    import numba  # noqa: F401
from numba.core.caching import IndexDataCacheFile

read = IndexDataCacheFile._load_index

def slow_read(self):  # widen the window between reading the index and writing it
    overloads = read(self)
    time.sleep(1.0)
    return overloads

IndexDataCacheFile._load_index = slow_read
cache = IndexDataCacheFile(sys.argv[1], "kernel", "stamp")
from pathlib import Path
(Path(sys.argv[1]) / f"ready-{sys.argv[2]}").touch()
while not (Path(sys.argv[1]) / "go").exists():  # both start saving at once
    time.sleep(0.005)
cache.save(sys.argv[2], sys.argv[3])
"""


def _race(folder, mode: str) -> dict:
    """Two processes that each save one entry of one cache at the same moment; what a third
    then loads for each key."""
    writers = [subprocess.Popen([sys.executable, "-c", RACE, str(folder), key, f"code of {key}",
                                 mode]) for key in ("int32", "int64")]
    deadline = time.monotonic() + 120
    while not all((folder / f"ready-{key}").exists() for key in ("int32", "int64")):
        assert time.monotonic() < deadline and all(w.poll() is None for w in writers)
        time.sleep(0.01)
    (folder / "go").touch()
    assert [w.wait(timeout=120) for w in writers] == [0, 0]
    from numba.core.caching import IndexDataCacheFile

    cache = IndexDataCacheFile(str(folder), "kernel", "stamp")
    return {key: cache.load(key) for key in ("int32", "int64")}


def test_concurrent_cache_writes_keep_each_entry_its_own_code(tmp_path):
    """With the lock each key loads its own code; numba's own save, in the same race, leaves
    one key without an entry or naming the other's code (numba/numba#4807)."""
    (tmp_path / "locked").mkdir()
    assert _race(tmp_path / "locked", "lock") == {"int32": "code of int32",
                                                  "int64": "code of int64"}
    (tmp_path / "plain").mkdir()
    assert _race(tmp_path / "plain", "plain") != {"int32": "code of int32",
                                                  "int64": "code of int64"}


def test_numba_inlines_a_fresh_callee_in_place_into_the_same_machine_code():
    """numba's inliner splices each callee's fresh IR without its two unread deep copies
    (:func:`impactsph.jitcache.inline_fresh_ir_in_place`, which ``import impactsph`` applies):
    a function calling nested ``inline="always"`` helpers, with loops, branches and an
    ``@overload`` inlined through the typed path, compiles to the same machine code as with
    numba's own inliner (on the 2D pair pass too: 22-23 s of compile time against 28-29 s,
    same code, measured in issue 16's closing note)."""
    import numba as nb
    import numpy as np
    from numba.core import inline_closurecall

    from impactsph.jitcache import inline_fresh_ir_in_place, normalised_machine_code
    from impactsph.kernels import cubic_spline_gradient_factor
    from impactsph.physics.records import record_coordinate

    assert inline_fresh_ir_in_place(), (
        "numba's inliner has changed: impactsph.jitcache.inline_fresh_ir_in_place no longer "
        "applies (its unread copies may be gone upstream: check, then update or remove it)")
    in_place = inline_closurecall.InlineWorker.inline_function
    assert in_place.fresh_ir_in_place

    @nb.njit(inline="always")
    def limited(value, bound):
        if value > bound:
            return bound
        total = 0.0
        for k in range(3):
            total += value / (k + 1.0)
        return total

    @nb.njit(inline="always")
    def pair_term(records, i, j, h):
        r = abs(record_coordinate(records, i, 0, 0, 1) - record_coordinate(records, j, 0, 0, 1))
        return limited(cubic_spline_gradient_factor(r / h, 1.0 / h, 2), 1e3)

    def outer(records, h):
        total = 0.0
        for i in range(records.shape[0]):
            for j in range(records.shape[0]):
                if i != j:
                    total += pair_term(records, i, j, h)
        return total

    records = np.linspace(0.0, 1.0, 12).reshape(-1, 1)
    code, values = {}, {}
    try:
        for name, inline_function in (("numba", in_place.numba_original),
                                      ("in place", in_place)):
            inline_closurecall.InlineWorker.inline_function = inline_function
            compiled = nb.njit(outer)
            values[name] = compiled(records, 0.3)
            code[name] = normalised_machine_code(compiled)
    finally:
        inline_closurecall.InlineWorker.inline_function = in_place
    assert values["in place"] == values["numba"] != 0.0
    assert code["in place"] == code["numba"]
    assert "cubic_spline_gradient_factor" not in code["in place"]  # (inlined: no call left)


def test_numba_copies_its_sets_of_names_into_the_same_machine_code():
    """numba's copy propagation and alias analysis copy their maps of variable names without
    ``copy.deepcopy`` (:func:`impactsph.jitcache.copy_sets_of_names_shallowly`, which ``import
    impactsph`` applies): the copy equals the deep copy and shares no set with the original;
    anything else is still deep-copied; and a parallel function (a ``prange`` loop, whose
    passes run the copy propagation) compiles to the same machine code as with ``deepcopy``
    (on a cold Taylor run: those copies 18.5 s, 2.1 s after)."""
    import copy
    from types import SimpleNamespace

    import numba as nb
    import numpy as np
    from numba.core import ir_utils

    from impactsph.jitcache import (
        _sets_of_names,
        copy_sets_of_names_shallowly,
        normalised_machine_code,
    )

    assert copy_sets_of_names_shallowly(), (
        "numba.core.ir_utils no longer imports copy: impactsph.jitcache."
        "copy_sets_of_names_shallowly no longer applies (check, then update or remove it)")
    changed = ir_utils.copy
    names = {3: {("a", "$b"), ("c", "d")}, 7: set(), "x": {"y", ("z", "w")}}
    copied = changed.deepcopy(names)
    assert copied == copy.deepcopy(names) and copied is not names
    assert all(copied[key] is not names[key] for key in names)
    names[3].add(("e", "f"))
    assert ("e", "f") not in copied[3]
    block = {1: {(object(), "a")}}  # not names: deep-copied as before
    assert next(iter(changed.deepcopy(block)[1]))[0] is not next(iter(block[1]))[0]

    def smooth(values, out):
        for i in nb.prange(values.shape[0] - 2):
            a = values[i]
            b = a
            c = values[i + 1] if i % 2 else b
            total = 0.0
            for k in range(3):
                total += c * (k + 1.0) - values[i + 2]
            out[i] = total + b
        return out.sum()

    copies_of_names = []

    def counted(value, memo=None):
        copies_of_names.append(_sets_of_names(value))
        return changed.deepcopy(value, memo)

    values = np.linspace(0.0, 1.0, 40)
    code, sums = {}, {}
    try:
        for name, module in (("deepcopy", copy),
                             ("sets", SimpleNamespace(**{**vars(changed), "deepcopy": counted}))):
            ir_utils.copy = module
            compiled = nb.njit(parallel=True)(smooth)
            sums[name] = compiled(values, np.zeros(40))
            code[name] = normalised_machine_code(compiled)
    finally:
        ir_utils.copy = changed
    assert sums["sets"] == sums["deepcopy"] != 0.0
    assert code["sets"] == code["deepcopy"]
    assert any(copies_of_names)  # the parallel passes took the new copy


def test_compile_log_names_each_compilation(tmp_path):
    """``IMPACTSPH_COMPILE_LOG``: each process appends a line per function numba compiles,
    with its time, nesting depth and the test that asked (none here); a second process that
    loads the function from the cache writes nothing."""
    script = ("import impactsph, numba as nb\n"
              "@nb.njit(cache=True)\n"
              "def doubled(a):\n"
              "    return 2.0 * a\n"
              "print(doubled(1.5))\n")
    (tmp_path / "job.py").write_text(script)
    log = tmp_path / "compiles.tsv"
    env = dict(os.environ, IMPACTSPH_COMPILE_LOG=str(log), NUMBA_CACHE_DIR=str(tmp_path / "c"))
    for _ in range(2):
        done = subprocess.run([sys.executable, str(tmp_path / "job.py")], env=env,
                              capture_output=True, text=True, check=True, cwd=tmp_path)
        assert done.stdout.strip() == "3.0"
    lines = [line.split("\t") for line in log.read_text().splitlines()]
    assert [(depth, name) for _, _, depth, name, _ in lines] == [("0", "__main__.doubled")]
    assert int(lines[0][0]) > 0 and float(lines[0][1]) > 0.0


# -- a kernel's cache stale when another file of its package changes ---------------------------

PACKAGE_SCRIPT = r"""
import sys
sys.path.insert(0, sys.argv[1])
if sys.argv[2] == "stamped":
    from impactsph.jitcache import stamp_package_sources
    stamp_package_sources(sys.argv[1] + "/toy")
from toy.kernel import twice
print(twice(1.0), sum(twice.stats.cache_hits.values()))
"""


def _toy_package(root, value: float) -> None:
    """``toy``: ``kernel.twice`` (cached) returns ``2 * constants.VALUE``."""
    package = root / "toy"
    package.mkdir(exist_ok=True)
    (package / "__init__.py").write_text("")
    (package / "constants.py").write_text(f"VALUE = {value!r}\n")
    (package / "kernel.py").write_text(
        "import numba as nb\nfrom .constants import VALUE\n\n\n"
        "@nb.njit(cache=True)\ndef twice(x):\n    return 2.0 * VALUE * x\n")


def _toy_run(root, cache, how: str) -> tuple[float, int]:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    done = subprocess.run([sys.executable, "-c", PACKAGE_SCRIPT, str(root), how], env=env,
                          capture_output=True, text=True, check=True)
    value, hits = done.stdout.split()
    return float(value), int(hits)


def test_a_kernel_sees_its_packages_new_constant_with_the_stamp(tmp_path):
    """numba keys a cached kernel on its own file: with a constant changed in another file
    of its package, the kernel loaded from the cache still returns the old value (the
    plain rows, which show the hazard), unless the package's files are in the stamp
    (:func:`impactsph.jitcache.stamp_package_sources`); an unchanged package loads its
    kernel from the cache, stamped or not."""
    for how in ("plain", "stamped"):
        root, cache = tmp_path / how, tmp_path / f"{how}-cache"
        root.mkdir()
        _toy_package(root, 1.5)
        assert _toy_run(root, cache, how) == (3.0, 0)  # compiled
        _toy_package(root, 2.5)  # constants.py edited, kernel.py the same
        value, hits = _toy_run(root, cache, how)
        if how == "plain":
            assert (value, hits) == (3.0, 1)  # numba's own cache: the stale value
        else:
            assert (value, hits) == (5.0, 0)  # compiled again with the new value
            assert _toy_run(root, cache, how) == (5.0, 1)  # and from the cache after


def test_the_packages_own_kernels_carry_its_digest_in_their_stamp():
    """``import impactsph`` stamps its own files' kernels with the digest of its sources; a
    function outside the package keeps numba's stamp."""
    import numba as nb
    from numba.core.caching import CompileResultCacheImpl

    import impactsph
    from impactsph.jitcache import package_digest
    from impactsph.solver import value_range

    folder = os.path.realpath(os.path.dirname(impactsph.__file__))
    stamp = CompileResultCacheImpl(value_range.py_func).locator.get_source_stamp()
    assert stamp[1] == package_digest(folder)

    @nb.njit(cache=True)
    def outside(x):  # pragma: no cover (compiled)
        return x

    theirs = CompileResultCacheImpl(outside.py_func).locator.get_source_stamp()
    assert not (isinstance(theirs, tuple) and len(theirs) == 2
                and theirs[1] == package_digest(folder))


STRETCH = r"""
import json
import numpy as np
from impactsph.physics.stretch import _stretch_kernel
out = {}
for dim in (2, 3):
    X = np.array(np.meshgrid(*[np.arange(3.0)] * dim)).reshape(dim, -1).T.copy()
    n = X.shape[0]
    F = np.eye(dim) + 0.1 * np.arange(dim * dim).reshape(dim, dim) / dim ** 2
    x = X @ F.T
    offsets = np.arange(n + 1, dtype=np.int32) * (n - 1)
    indices = np.array([j for i in range(n) for j in range(n) if j != i], dtype=np.int32)
    kernel = _stretch_kernel(dim)
    lam = kernel(np.arange(n, dtype=np.int32), offsets, indices, x, X,
                 np.zeros(n, np.int32), np.full(n, 1.5), n)
    out[dim] = [float(lam[n // 2]), sum(kernel.stats.cache_hits.values()),
                sum(kernel.stats.cache_misses.values())]
print(json.dumps(out))
"""


def test_a_second_process_finds_the_stretch_kernel_in_the_cache(tmp_path):
    """The smoothing length that follows the stretch (on by default where a material yields)
    compiled again in every process, 1.35 s in 2D and 2.1 s in 3D, and each run added an entry
    to numba's cache: its kernel held the row function, a compiled closure, whose pickle
    carries an id of its process, and numba's cache key hashes a closure's contents."""
    def run() -> dict:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
        done = subprocess.run([sys.executable, "-c", STRETCH], env=env, capture_output=True,
                              text=True, check=True)
        return json.loads(done.stdout.strip().splitlines()[-1])

    first, second = run(), run()
    for dim in ("2", "3"):
        assert first[dim][1:] == [0, 1] and second[dim][1:] == [1, 0], (first, second)
        assert second[dim][0] == first[dim][0] > 1.0
    assert len(list(tmp_path.rglob("*stretches_2d*.nbc"))) == 1


CLOSURES = r"""
import hashlib, json
from numba.core.serialize import dumps
from impactsph import integrate, neighbours
from impactsph.physics import stretch, total_lagrangian

found, todo = {}, []
for dim in (1, 2, 3):
    todo += [*neighbours._build_functions(dim), integrate._survey_kernel(dim),
             stretch._stretch_kernel(dim), *vars(total_lagrangian.compiled_passes(dim)).values()]
while todo:
    f = todo.pop()
    py = getattr(f, "py_func", f)
    cells = getattr(py, "__closure__", None) or ()
    if hasattr(f, "py_func") and f._cache.__class__.__name__ != "NullCache":
        key = f"{py.__module__}.{py.__qualname__}"
        found[key] = hashlib.sha256(dumps(tuple(c.cell_contents for c in cells))).hexdigest()
    todo += [c.cell_contents for c in cells if callable(c.cell_contents)
             and not isinstance(c.cell_contents, type) and c.cell_contents is not f]
print(json.dumps(found))
"""


def test_every_cached_closure_kernel_has_the_same_cache_key_in_every_process():
    """numba finds a closure's compiled code in its cache only where the closure's contents
    pickle to the same bytes in the next process (its index key hashes them): numbers and
    arrays do, a compiled function does not (its pickle names its process's id).  So no
    cached kernel compiled from a closure (a dimension's variant) may hold another compiled
    function; it calls it as a global (``stretch.stretch_row`` with ``dim`` passed)."""
    def run() -> dict:
        done = subprocess.run([sys.executable, "-c", CLOSURES], capture_output=True, text=True,
                              check=True)
        return json.loads(done.stdout.strip().splitlines()[-1])

    first, second = run(), run()
    assert len(first) >= 20, sorted(first)
    assert any("stretches_3d" in name for name in first)
    assert {k for k in first if first[k] != second.get(k)} == set()


RECOMPILES = r"""
import json

from numba.core import event
from impactsph import Simulation, load_case

compiled = []


class Listener(event.Listener):
    def on_start(self, ev):
        pass

    def on_end(self, ev):  # a compilation, not a load from the cache
        function = ev.data["dispatcher"].py_func
        name = f"{function.__module__}.{function.__qualname__}"
        if name.startswith("impactsph"):
            compiled.append(name)


event.register("numba:compile", Listener())
for case, overrides in (
        ("taylor", ["kernel.max_stretch=1.23", "time.max_steps=40"]),
        ("taylor3d", ["time.max_steps=12", "bodies.0.geometry.spacing=1.2e-3"]),
        ("bars", ["time.max_steps=20"])):
    Simulation(load_case(case, ["output.figures=false", *overrides])).run()
print(json.dumps(sorted(set(compiled))))
"""


def test_a_second_process_compiles_nothing():
    """Runs of the built-in cases (2D with the stretch and a wall, 3D with the stretch, 1D)
    compile whatever the cache lacks in a first process, and nothing in a second: every
    kernel a run calls is found in numba's cache (the stretch kernel was not, until
    2026-12-07, and compiled in every run)."""
    def run() -> list:
        done = subprocess.run([sys.executable, "-c", RECOMPILES], capture_output=True,
                              text=True, check=True)
        return json.loads(done.stdout.strip().splitlines()[-1])

    run()
    assert run() == []


def test_the_compile_timer_counts_numbas_compiling_once_and_only_inside():
    """:class:`CompileTimer` counts the seconds numba holds its compiler lock inside the
    ``with``: a new function's compilation (its callee's inside it, counted once), not the
    calls of compiled code, nor compilations before or after."""
    import numba as nb

    from impactsph.jitcache import CompileTimer

    @nb.njit
    def callee(x):
        return x * 2.0

    @nb.njit
    def caller(x):
        return callee(x) + 1.0

    @nb.njit
    def later(x):
        return x - 1.0

    with CompileTimer() as timer:
        started = time.perf_counter()
        assert caller(1.0) == 3.0  # compiles caller and, inside it, callee
        first = time.perf_counter() - started
        compiled = timer.seconds
        started = time.perf_counter()
        for _ in range(1000):
            caller(1.0)
        calls = time.perf_counter() - started
    assert 0.5 * first < compiled <= first  # the compilation is most of the first call
    assert timer.seconds == compiled and calls < compiled  # the calls add nothing
    later(1.0)  # after the with: not counted
    assert timer.seconds == compiled
    # a hold that began before the timer was entered (in another thread) ends inside it:
    # nothing to count, and the next hold is counted from its own start
    late = CompileTimer()
    late._end(None)
    late._start(None)
    time.sleep(0.02)
    late._end(None)
    assert 0.02 <= late.seconds < 0.5


def test_a_runs_compile_time_is_counted_and_left_out_of_its_pair_rate():
    """A run's ``compile_seconds`` holds what numba compiled inside its loop (here a new
    function a callback calls), and the summary's pair rate is over the rest of its time."""
    import numba as nb

    from impactsph import Simulation, load_case

    @nb.njit
    def fresh(x):  # compiled at the callback's first call, inside the run's loop
        return x + 1.0

    seconds = []

    def callback(sim):
        if not seconds:
            started = time.perf_counter()
            fresh(1.0)
            seconds.append(time.perf_counter() - started)

    sim = Simulation(load_case("bars", ["time.end=2e-6"]))
    sim.run(callback=callback)
    record, summary = sim.record, sim.summary()
    assert 0.5 * seconds[0] <= record.compile_seconds <= record.wall_seconds
    assert summary["compile_seconds"] == record.compile_seconds
    assert summary["pair_evaluations_per_second"] == (
        summary["pair_evaluations"] / (record.wall_seconds - record.compile_seconds))


def test_the_run_log_says_when_compiling_took_a_tenth_of_the_run():
    """The log's "finished" line names the compiling where it is a tenth of the wall time or
    more, and 0.1 s or more (the Taylor bar's 76 steps after an upgrade: 1.73 s of 1.81 s),
    not a warm run's loads (0.02 s of 1.36 s)."""
    from impactsph.runner import compiling_note
    from impactsph.simulation import RunRecord

    assert compiling_note(RunRecord(wall_seconds=1.81, compile_seconds=1.73)) == (
        ", 1.73 s of it numba compiling or loading code")
    assert compiling_note(RunRecord(wall_seconds=1.36, compile_seconds=0.02)) == ""
    # nor a tiny run's loads (the bars to 2 us: 7.6 ms of 41 ms)
    assert compiling_note(RunRecord(wall_seconds=0.041, compile_seconds=0.0076)) == ""
    assert compiling_note(RunRecord()) == ""
