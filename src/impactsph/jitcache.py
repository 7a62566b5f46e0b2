"""Numba's on-disk cache for kernels compiled once per variant (a dimension) from one closure.

Numba names a function's cache files after its module, qualified name and line, so every
variant of a closure built in a factory (``_build_functions(dim)``'s ``build``) shares one
index file and numbers its data files from 1 in it.  Two processes that compile two variants
at once (the test run's two workers, or two runs started side by side on a fresh cache) each
read the index before the other wrote it, both write their code to data file 1, and the index
of one ends up naming the code of the other: the next process that loads it runs a kernel
compiled for other arrays and crashes ("NRT_adapt_ndarray_to_python: descr is NULL").
:func:`njit_variant` gives each variant a qualified name of its own, hence files of its own,
and a variant is always compiled for one signature, so concurrent writers of one file write
the same code.

A function compiled for two signatures (two callers passing int32 and int64 arrays) has the
same race between its two entries (numba/numba#4807, open).  :func:`lock_cache_writes`, which
``import impactsph`` calls, closes it for every cached function of the process: a cache
entry is written under an exclusive lock on its index (``fcntl.flock`` on ``<index>.lock``),
the index read inside the lock, and the code file written before the index that names it.

:func:`inline_fresh_ir_in_place` cuts the compile time of the passes, whose model calls are
inlined by numba (``inline="always"``): numba builds a fresh IR of the callee for every call
site, then deep-copies it twice before splicing it in, copies nobody reads (numba/numba#8989;
numba-cuda's own copy of the inliner, NVIDIA/numba-cuda#688).  Skipping them changes no
compiled instruction (the test compares the machine code).  :func:`copy_sets_of_names_shallowly`
does the same for the maps of variable names that numba's copy propagation and alias analysis
deep-copy at every round.
"""

from __future__ import annotations

import contextvars
import copy
import functools
import hashlib
import inspect
import itertools
import os
import re
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba as nb


def njit_variant(variant: str, **options: Any) -> Callable[[Callable], Any]:
    """``numba.njit(cache=True, **options)`` for one ``variant`` (e.g. ``"3d"``) of a closure:
    the function's qualified name gets ``_<variant>``, so that its cache files are its own."""
    if not re.fullmatch(r"\w+", variant):
        raise ValueError(f"variant = {variant!r}: a cache variant is letters, digits and _")

    def decorate(function: Callable) -> Any:
        function.__qualname__ = f"{function.__qualname__}_{variant}"
        return nb.njit(cache=True, **options)(function)

    return decorate


def stamp_package_sources(package: str | os.PathLike) -> bool:
    """Make numba's cache entries of the functions compiled from the files of ``package`` (a
    folder) stale when any Python file of that folder changes: wrap
    ``numba.core.caching._SourceFileBackedLocatorMixin.get_source_stamp``, whose stamp (of
    the function's own file: numba 0.68 hashes its content) numba stores in a cache index and
    compares when it loads, so that for those files it is ``(numba's stamp,
    package_digest(package))``.

    numba keys an entry on the function's own file only, but a kernel holds the constants it
    read from other modules and the compiled functions of other modules it called, as they
    were when it was compiled: ``integrate.py``'s survey kernels keep
    ``physics/survey.SURVEY_CHUNK`` and ``survey_particle``.  Edited there alone (by a
    developer, or by a pull into an editable install), those kernels ran with the old values:
    runs failed at their first step (2026-12-06).  The passes generated from the template
    are named by a hash of every source they inline (:mod:`impactsph.codegen`) and live
    outside the package, so this leaves them alone; the package's own kernels compile again
    after any edit of it (about 110 s of the test suite's compiling).  Returns whether the
    stamp is in place: False where numba's locator no longer has the method."""
    try:
        from numba.core.caching import _SourceFileBackedLocatorMixin as Locator
    except ImportError:
        return False
    original = getattr(Locator, "get_source_stamp", None)
    if original is None:
        return False
    root = os.path.realpath(package)
    folders = getattr(original, "impactsph_roots", None)
    if folders is not None:  # already wrapped: this folder too
        folders.add(root)
        return True

    def get_source_stamp(self):
        stamp = original(self)
        path = getattr(self, "_py_file", None)
        if not isinstance(path, str):
            return stamp
        path = os.path.realpath(path)
        for folder in get_source_stamp.impactsph_roots:
            if path.startswith(folder + os.sep):
                return stamp, package_digest(folder)
        return stamp

    get_source_stamp.impactsph_roots = {root}
    Locator.get_source_stamp = get_source_stamp
    return True


@functools.cache
def package_digest(folder: str) -> str:
    """SHA-256 of every Python file below ``folder``, with its path relative to it, in
    sorted order (read once a process: some 60 files)."""
    digest = hashlib.sha256()
    for path in sorted(Path(folder).rglob("*.py")):
        digest.update(path.relative_to(folder).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def lock_cache_writes() -> bool:
    """Make numba's cache writes safe between processes (above): wrap
    ``numba.core.caching.IndexDataCacheFile.save``.  Returns whether the lock is in place:
    False where ``fcntl`` is missing (Windows) or numba's cache file class no longer has the
    private methods the wrapper calls, which leaves numba's own ``save``."""
    try:
        import fcntl

        from numba.core.caching import IndexDataCacheFile
    except ImportError:
        return False
    original = IndexDataCacheFile.save
    if getattr(original, "locked_by_impactsph", False):
        return True
    if not all(callable(getattr(IndexDataCacheFile, name, None))
               for name in ("_load_index", "_save_index", "_save_data", "_data_name")):
        return False

    def save(self, key, data):
        index = getattr(self, "_index_path", None)
        if index is None:  # another numba's layout: its own way
            return original(self, key, data)
        try:
            handle = open(f"{index}.lock", "a")  # noqa: SIM115 (closed below)
        except OSError:  # a cache folder that cannot be written: numba's own way
            return original(self, key, data)
        with handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes
            except OSError:  # a file system without locks
                return original(self, key, data)
            overloads = self._load_index()
            name = overloads.get(key)
            if name is None:
                taken = set(overloads.values())
                name = next(self._data_name(i) for i in itertools.count(1)
                            if self._data_name(i) not in taken)
                self._save_data(name, data)  # the code, then the index that names it
                overloads[key] = name
                self._save_index(overloads)
            else:
                self._save_data(name, data)

    save.locked_by_impactsph = True
    IndexDataCacheFile.save = save
    return True


def _copy_module_with(deepcopy: Callable[..., Any]) -> types.SimpleNamespace:
    """The ``copy`` module with its ``deepcopy`` replaced: what a numba module that imports
    ``copy`` gets as its ``copy`` (the rest of the module, ``copy.copy`` included, unchanged)."""
    return types.SimpleNamespace(**{**vars(copy), "deepcopy": deepcopy})


#: set while :func:`inline_fresh_ir_in_place`'s ``inline_function`` splices a callee's fresh IR
_FRESH_IR = contextvars.ContextVar("impactsph_fresh_inline_ir", default=False)


def _deepcopy_unless_fresh(value: Any, memo: dict | None = None) -> Any:
    """``copy.deepcopy``, except on the blocks of a fresh callee IR (returned as they are)."""
    return value if _FRESH_IR.get() else copy.deepcopy(value, memo)


def inline_fresh_ir_in_place(module: types.ModuleType | None = None) -> bool:
    """Make numba's inliner splice a callee's fresh IR without copying it first.

    ``InlineWorker.inline_function`` (the ``inline="always"`` of ``@njit`` functions) runs
    the untyped passes on the callee for each call site, so the IR it hands to ``inline_ir``
    is its own; ``inline_ir`` deep-copies it block by block all the same ("it gets mutated"),
    and once more for an unmutated copy that both of numba's callers discard.  Without them
    the 2D pair pass and stage compile in 0.78-0.87 of the CPU time, to the same machine code
    (``benchmarks/bench_compile.py``; docs/architecture.md, "Compile time").
    Here, while ``inline_function`` calls ``inline_ir``, that module's ``copy.deepcopy``
    returns the blocks as they are; an IR numba keeps (an ``@overload``'s, inlined through
    ``inline_ir`` directly) is copied as before.

    ``module`` is numba's ``numba.core.inline_closurecall`` (the default) or numba-cuda's
    copy of it.  Returns whether the change is in place: False, leaving numba's own way,
    where the module no longer has the structure this relies on (one ``copy.deepcopy`` in
    ``inline_ir``, ``inline_function`` calling ``run_untyped_passes`` then ``inline_ir``).
    ``IMPACTSPH_NUMBA_INLINE_COPIES=1`` in the environment keeps numba's copies."""
    if module is None:
        try:
            from numba.core import inline_closurecall as module
        except ImportError:
            return False
    worker = getattr(module, "InlineWorker", None)
    if worker is None:
        return False
    if getattr(worker.inline_function, "fresh_ir_in_place", False):
        return True
    if os.environ.get("IMPACTSPH_NUMBA_INLINE_COPIES", "") not in ("", "0"):
        return False
    try:
        inline_ir = inspect.getsource(worker.inline_ir)
        inline_function = inspect.getsource(worker.inline_function)
    except (AttributeError, OSError, TypeError):
        return False
    if (getattr(module, "copy", None) is not copy or inline_ir.count("copy.deepcopy(") != 1
            or "self.run_untyped_passes(function)" not in inline_function
            or "self.inline_ir(" not in inline_function):
        return False

    def inline_function_in_place(self, caller_ir, block, i, function, arg_typs=None):
        callee_ir = self.run_untyped_passes(function)  # a fresh IR: nobody else holds it
        token = _FRESH_IR.set(True)
        try:
            return self.inline_ir(caller_ir, block, i, callee_ir,
                                  function.__code__.co_freevars, arg_typs=arg_typs)
        finally:
            _FRESH_IR.reset(token)

    inline_function_in_place.fresh_ir_in_place = True
    inline_function_in_place.numba_original = worker.inline_function
    inline_function_in_place.__doc__ = worker.inline_function.__doc__
    module.copy = _copy_module_with(_deepcopy_unless_fresh)
    worker.inline_function = inline_function_in_place
    return True


def _sets_of_names(value: Any) -> bool:
    """Whether ``value`` is a dict (keys int or str) of sets whose members are names (str) or
    tuples of names: what numba's copy propagation and alias analysis deep-copy.  (The
    members' types are gathered with ``map``, in C: the maps hold thousands of pairs.)"""
    if type(value) is not dict:
        return False
    for key, members in value.items():
        if type(key) not in (int, str) or type(members) is not set:
            return False
        kinds = set(map(type, members))
        if tuple in kinds:
            kinds.discard(tuple)
            tuples = members if not kinds else [m for m in members if type(m) is tuple]
            if set(map(type, itertools.chain.from_iterable(tuples))) - {str}:
                return False
        if kinds - {str}:
            return False
    return True


def _deepcopy_sets_of_names(value: Any, memo: dict | None = None) -> Any:
    """``copy.deepcopy``, except on a dict of sets of names (:func:`_sets_of_names`): a new
    dict of new sets of the same members, which is what ``deepcopy`` makes of them (a str, or
    a tuple of str, deep-copies to itself)."""
    if memo is None and _sets_of_names(value):
        return {key: set(members) for key, members in value.items()}
    return copy.deepcopy(value, memo)


def copy_sets_of_names_shallowly(module: types.ModuleType | None = None) -> bool:
    """Make numba's copy propagation and alias analysis copy their sets of variable names
    without ``copy.deepcopy``'s walk over every member.

    ``ir_utils.copy_propagate`` iterates its data-flow equations to a fixed point and
    deep-copies the whole ``{block: {(lhs, rhs), ...}}`` map at each round to compare;
    ``find_potential_aliases`` deep-copies its ``{name: {name, ...}}`` map.  In a parallel
    pass, whose ``prange`` body is large once the models are inlined, these copies were the
    largest single cost of a compile in a profile of a cold Taylor run.  Here the module's
    ``copy.deepcopy`` gives, for a dict of sets of names, a new dict of new sets of the same
    members (:func:`_deepcopy_sets_of_names`): equal to the deep copy, and just as free of the
    original's later changes; anything else is deep-copied as before.

    ``module`` is ``numba.core.ir_utils`` (the default) or numba-cuda's copy of it.  Returns
    whether the change is in place: False where the module has no ``copy`` module of its own
    (numba changed), or ``IMPACTSPH_NUMBA_DEEPCOPY=1`` is set, which keeps numba's way."""
    if module is None:
        try:
            from numba.core import ir_utils as module
        except ImportError:
            return False
    current = getattr(module, "copy", None)
    if getattr(current, "deepcopy", None) is _deepcopy_sets_of_names:
        return True
    if current is not copy or os.environ.get("IMPACTSPH_NUMBA_DEEPCOPY", "") not in ("", "0"):
        return False
    module.copy = _copy_module_with(_deepcopy_sets_of_names)
    return True


def normalised_machine_code(dispatcher: Any, signature: Any = None) -> str:
    """A compiled function's assembly (its first signature's unless ``signature`` is given)
    without what differs between two compilations of the same code in one process: the
    names' compile counters (``B3v74``), the addresses in names, and so the lengths of the
    error messages that hold a name.  Two compilations that give the same text run the same
    instructions (:func:`inline_fresh_ir_in_place`'s test, ``benchmarks/bench_compile.py``)."""
    asm = dispatcher.inspect_asm(signature if signature is not None
                                 else dispatcher.signatures[0])
    asm = re.sub(r"0x[0-9a-f]+", "0x", re.sub(r"B\d+v\d+", "Bv", asm))
    return re.sub(r'(\.size\t".*"), \d+$', r"\1, n", asm, flags=re.M)


def log_compiles(path: str | os.PathLike) -> None:
    """Append a line to ``path`` for each function numba compiles in this process (not those
    it loads from its cache): ``process id, seconds, nesting depth, qualified name`` and,
    inside a test run, the test that asked for it (``$PYTEST_CURRENT_TEST``), tab separated,
    written when the compilation ends.  A function compiled inside another's
    compilation (a callee) has depth 1 or more, and its time is part of its caller's.

    ``import impactsph`` calls it with ``$IMPACTSPH_COMPILE_LOG`` when that is set, so that
    every process of a run (the test run's workers and the processes they start) writes to one
    file: where a cold cache's time goes (docs/architecture.md, "Compile time")."""
    import time

    from numba.core import event

    started: list[float] = []
    pid = os.getpid()

    class _Logger(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            started.append(time.perf_counter())

        def on_end(self, ev: event.Event) -> None:
            seconds = time.perf_counter() - started.pop()
            function = ev.data["dispatcher"].py_func
            name = f"{function.__module__}.{function.__qualname__}"
            test = os.environ.get("PYTEST_CURRENT_TEST", "")
            with open(path, "a") as log:  # one short write: whole lines between processes
                log.write(f"{pid}\t{seconds:.3f}\t{len(started)}\t{name}\t{test}\n")

    event.register("numba:compile", _Logger())


#: the event module of numba and of numba-cuda (which has its own lock, and takes numba's
#: too where numba is installed), and the event each fires while its compiler lock is held:
#: compiling a function, or loading it from the disk cache
_LOCK_EVENTS = (("numba.core.event", "numba:compiler_lock"),
                ("numba.cuda.core.event", "numba-cuda:compiler_lock"))


class CompileTimer:
    """The seconds numba spends compiling or loading compiled code from its cache while the
    timer is entered (``with CompileTimer() as timer: ...; timer.seconds``): the time its
    compiler lock is held, the outermost hold only (a callee's compilation and numba-cuda's
    lock, which takes numba's, are inside their caller's).  What a run's time owes to the
    code rather than the steps: a first run's, or a short run's loads of its kernels
    (:attr:`impactsph.simulation.RunRecord.compile_seconds`)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._depth = 0
        self._since = 0.0
        self._registered: list[tuple[Any, str, Any]] = []

    def _start(self, ev: Any) -> None:
        if self._depth == 0:
            self._since = time.perf_counter()
        self._depth += 1

    def _end(self, ev: Any) -> None:
        if self._depth == 0:  # a hold that began before the timer (another thread's)
            return
        self._depth -= 1
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._since

    def __enter__(self) -> CompileTimer:
        import sys

        import numba.core.event  # noqa: F401 (loaded; numba-cuda's module only if in use)

        for name, kind in _LOCK_EVENTS:
            module = sys.modules.get(name)
            if module is None:
                continue
            listener = type("_Listener", (module.Listener,),
                            {"on_start": lambda _, ev: self._start(ev),
                             "on_end": lambda _, ev: self._end(ev)})()
            module.register(kind, listener)
            self._registered.append((module, kind, listener))
        return self

    def __exit__(self, *exc: object) -> None:
        for module, kind, listener in self._registered:
            module.unregister(kind, listener)
        self._registered.clear()


def noalias_option() -> dict[str, bool]:
    """``{"_noalias": True}`` for a decorator's keywords where numba can take it, else ``{}``.

    numba compiles a ``prange`` loop's body with its pointer arguments marked ``noalias``
    (``Flags.noalias``, where it finds no two arguments aliasing), so LLVM knows a store to an
    output cannot change an input.  Its decorators have no keyword for that flag; this adds
    one, ``_noalias``, to :class:`numba.core.cpu.CPUTargetOptions`, for the chunked passes
    (:mod:`impactsph.physics.chunked`), which are no ``prange`` bodies but are called, as
    those were, with arrays that are all distinct (the 3D pair pass on one thread took 1.08x
    the ``prange`` body's time without it, 2026-12-05).  A numba without the flag gets
    ``{}``: the same results, a little slower."""
    try:
        from numba.core.compiler import Flags
        from numba.core.cpu import CPUTargetOptions
        from numba.core.options import TargetOptions
    except ImportError:  # pragma: no cover - a numba reorganised
        return {}
    if not isinstance(getattr(Flags, "noalias", None), property) and \
            "noalias" not in getattr(Flags, "options", {}):
        return {}
    if not isinstance(getattr(CPUTargetOptions, "_noalias", None), TargetOptions.Mapping):
        CPUTargetOptions._noalias = TargetOptions.Mapping("noalias")
    return {"_noalias": True}
