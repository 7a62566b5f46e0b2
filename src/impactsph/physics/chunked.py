"""The passes over chunks, run in shares on numba's threads (issue 16, 2026-12-05).

The neighbour passes that LLVM vectorises (:func:`~impactsph.physics.passes.pair_pass`, the
moment, gradient and hourglass passes, and a vectorised viscosity switch) are compiled with
reassociation (``PAIR_FASTMATH``).  As numba ``prange`` loops they came out as two codes: numba
compiles a threaded loop's body as a function of its own, links a copy into the pass and
optimises that copy again; the process that compiled the pass runs the first, numba's cache
holds the second, and reassociation lets the second optimisation order a sum otherwise.  A run
then differed in its last bits between the first process on a machine and every later one,
and from the serial passes (docs/architecture.md, "One compiled code a pass").

So these passes have no ``prange``: each takes ``(first, step, ...)`` and runs its share
``first`` of ``step`` of its chunks (a block of consecutive chunks, so that a thread's
particles are neighbours), and :func:`run_chunked` runs the ``step`` shares on numba's threads
through a small ``prange`` loop of its own (:func:`_drive`) that calls the pass at its address
(:func:`_call_at`): the loop holds no arithmetic, and the pass is not linked into it, so every
process, threaded or not, compiling or loading, runs the one code of the pass that numba
compiled and cached.  Each particle's sums are made by one thread in a fixed order whatever
the thread count.  (Calling the shares from a pool of Python threads instead cost 1.4x on
the Taylor bar's 1407 particles on two threads: each pass is a fraction of a millisecond
there, and the threads' hand-over is not.)  The pass's native entry is looked up once for its
arguments' types (:func:`_address`).  :func:`_call_at` builds its call with numba's private
calling-convention helpers, and numba is not pinned: where a numba release has changed them,
:func:`_drive` fails to compile, and the shares run on a pool of Python threads instead (the
same calls, so the same bits), with one ``RuntimeWarning`` that says so
(:func:`_drive_ready`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from operator import is_
from typing import Any

import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.callconv import excinfo_t
from numba.core.cpu_options import ParallelOptions
from numba.extending import intrinsic
from numba.np.ufunc import parallel as _numba_parallel

#: the ``parallel`` option of the chunked passes (and of the serial passes,
#: :data:`impactsph.physics.passes.PARALLEL_OPTION`): numba's parallel passes'
#: simplifications (copy propagation, dead code, array analysis), which a ``prange`` body gets
#: and without which the pair pass took 1.07-1.12x as long, and no transform (they have no
#: ``prange``)
SIMPLIFICATIONS_ONLY = ParallelOptions(
    {"comprehension": False, "reduction": False, "inplace_binop": False, "setitem": False,
     "numpy": False, "stencil": False, "fusion": False, "prange": False})

#: the marks around a tuple's elements in :func:`_flat` (no pass takes scalars of these types)
_OPEN, _CLOSE = np.uint8(0), np.uint16(0)


def _flat(arguments: tuple[Any, ...]) -> tuple[Any, ...]:
    """``arguments`` with each tuple among them spliced in between the marks ``_OPEN`` and
    ``_CLOSE``: numba's ``prange`` passes a tuple into its loop's body as its elements, and
    cannot pass one whose elements are tuples."""
    flat: list[Any] = []
    for a in arguments:
        if isinstance(a, tuple):
            flat += [_OPEN, *a, _CLOSE]
        else:
            flat.append(a)
    return tuple(flat)


def _grouped(flat_types: tuple[Any, ...]) -> list[tuple[int, int, Any]]:
    """``(start, stop, type)`` of each argument in :func:`_flat`'s types: one element, or the
    elements between the marks as a tuple."""
    groups, k = [], 0
    while k < len(flat_types):
        if flat_types[k] == types.uint8:
            stop = k + 1
            while flat_types[stop] != types.uint16:
                stop += 1
            groups.append((k + 1, stop, types.BaseTuple.from_types(flat_types[k + 1:stop])))
            k = stop + 1
        else:
            groups.append((k, k + 1, flat_types[k]))
            k += 1
    return groups


@intrinsic
def _call_at(typingctx, address, first, step, flat):
    """``f(first, step, *arguments)`` for the compiled function ``f`` (numba's calling
    convention, returning nothing) whose native entry is at ``address``, the ``arguments``
    given as :func:`_flat` makes them: a call through a pointer, so ``f``'s code is not linked
    into the caller."""
    if not isinstance(address, types.Integer) or not isinstance(flat, types.BaseTuple):
        return None
    groups = _grouped(tuple(flat))
    argument_types = (first, step, *(g[2] for g in groups))

    def codegen(context, builder, signature, args):
        at, share, shares, packed = args
        elements = [builder.extract_value(packed, k) for k in range(len(flat))]
        values = [share, shares]
        for start, stop, kind in groups:
            if stop - start == 1 and not isinstance(kind, types.BaseTuple):
                values.append(elements[start])
            else:
                values.append(context.make_tuple(builder, kind, elements[start:stop]))
        conv = context.call_conv
        function = builder.inttoptr(
            at, conv.get_function_type(types.none, argument_types).as_pointer())
        returned = conv.get_return_type(types.none).pointee
        result = cgutils.alloca_once(builder, returned)
        builder.store(cgutils.get_null_value(returned), result)
        excinfo = cgutils.alloca_once(builder, ir.PointerType(excinfo_t), name="excinfo")
        native = list(conv._get_arg_packer(argument_types).as_arguments(builder, values))
        code = builder.call(function, [result, excinfo, *native])
        status = conv._get_return_status(builder, code, builder.load(excinfo))
        with cgutils.if_unlikely(builder, status.is_error):
            conv.return_status_propagate(builder, status)
        return context.get_dummy_value()

    return types.none(address, first, step, flat), codegen


@nb.njit(parallel=True, cache=True)
def _drive(address, threads, flat):  # pragma: no cover (compiled)
    """The pass at ``address`` for each share ``(t, threads, *arguments)`` in parallel (the
    arguments as :func:`_flat` makes them)."""
    for t in nb.prange(threads):
        _call_at(address, t, threads, flat)


#: per chunked pass, the pass and its last call's arguments (held, so that their ids stay
#: theirs), their ids (:func:`_ids`), the address of its code compiled for their types,
#: :func:`_drive`'s compiled entry for them or None (:func:`_drive_ready`), their kinds
#: (:func:`_kinds`), whether one of them is a tuple (then :func:`_flat` must splice it) and
#: the arguments as :func:`_drive` takes them (:func:`_flat`'s, or the arguments themselves)
_ADDRESSES: dict[int, tuple[Any, tuple[Any, ...], tuple[Any, ...], int, Any,
                            tuple[Any, ...], bool, tuple[Any, ...]]] = {}

#: the scalar types the passes are handed, whose numba type is their type's (a set lookup,
#: not an isinstance); a number of another type is taken by its id
_NUMBER_TYPES = frozenset({int, float, bool, np.float64, np.float32, np.int64, np.int32,
                           np.intp, np.bool_})


def _ids(arguments: tuple[Any, ...]) -> tuple[Any, ...]:
    """The quick test that ``arguments`` are the last call's: a number's type (a new object
    each call, as ``float(elapsed)``: its id would miss every time), any other argument's
    id (3 us for 25 arguments)."""
    return tuple([type(a) if type(a) in _NUMBER_TYPES else id(a) for a in arguments])


def _kind(argument: Any) -> Any:
    """What fixes ``numba.typeof(argument)`` without typing it: for an ndarray the fields of
    numba's array type (dtype, dimensions, layout from the contiguity flags as numba reads
    them: "C" where C-contiguous, even if F-contiguous too, as an array of one row or
    column is; read-only, aligned), for a number its type, for a plain tuple its elements'
    kinds (numba types a tuple by its elements' types), for anything else its id.  (With
    both flags as the kind, a (2, 1) array and a (2, 3) one were of two kinds though numba
    types them the same: a pass handed each in turn was looked up afresh at every call,
    some 0.15 ms; the neighbour builder's two kinds of build, 2026-12-06.)"""
    if type(argument) is np.ndarray:
        flags = argument.flags
        layout = "C" if flags.c_contiguous else ("F" if flags.f_contiguous else "A")
        return (argument.dtype, argument.ndim, layout, flags.writeable, flags.aligned)
    if type(argument) in _NUMBER_TYPES:
        return type(argument)
    if type(argument) is tuple:
        return (tuple, *map(_kind, argument))
    return id(argument)


def _kinds(arguments: tuple[Any, ...]) -> tuple[Any, ...]:
    """The arguments' :func:`_kind`: equal kinds, equal types.  A new array of the same kind
    (a view made for the call, as ``offsets[:-1]``) then needs no typing: 7.7 us for 25
    arguments where typing them and the drive's tuple took some 0.6 ms, at every evaluation
    of a run whose pass got a new view each time (the 1D passes' row starts, 2026-12-06)."""
    return tuple(_kind(a) for a in arguments)


def _address(chunk_pass: Any, arguments: tuple[Any, ...]) -> tuple[int, Any, tuple[Any, ...]]:
    """The native entry of ``chunk_pass`` compiled for ``(0, 1, *arguments)``'s types
    (compiled, or loaded from numba's cache, on first use), :func:`_drive`'s compiled entry
    for them or None (:func:`_drive_ready`), and the arguments as :func:`_drive` takes them
    (:func:`_flat`'s where one is a tuple): looked up again only for arguments of other
    kinds than the last call's (:func:`_kinds`).  The spliced arguments of the last call are
    handed out again where the arguments are its very objects, numbers included (the pair
    pass's every call between two list builds: :func:`_flat` took 1-2 us of each)."""
    known = _ADDRESSES.get(id(chunk_pass))
    if (known is not None and known[0] is chunk_pass and len(arguments) == len(known[1])
            and all(map(is_, arguments, known[1]))):
        # the very objects of the last call, numbers too (an int a run keeps, a flag): its
        # address, drive and splice, without the ids (the pair pass's calls between two
        # list builds)
        return known[3], known[4], known[7] if known[6] else arguments
    ids = _ids(arguments)
    if known is not None and known[0] is chunk_pass:
        if known[2] == ids:  # the arrays held, a number new (the stage's step size)
            if not known[6]:
                return known[3], known[4], arguments
            kinds = known[5]
        else:
            kinds = _kinds(arguments)
        if known[5] == kinds:  # (new arrays of the same kinds: a list build's)
            flat = _flat(arguments) if known[6] else arguments
            _ADDRESSES[id(chunk_pass)] = (chunk_pass, arguments, ids, *known[3:7], flat)
            return known[3], known[4], flat
    else:
        kinds = _kinds(arguments)
    signature = tuple(nb.typeof(a) for a in (0, 1, *arguments))
    overload = chunk_pass.overloads.get(signature)
    if overload is None:
        chunk_pass.compile(signature)
        overload = chunk_pass.overloads[signature]
    at = overload.library.get_pointer_to_function(overload.fndesc.llvm_func_name)
    flat = _flat(arguments)
    drive = _drive_ready(at, flat)
    tupled = any(type(a) is tuple for a in arguments)
    if not tupled:
        flat = arguments
    _ADDRESSES[id(chunk_pass)] = (chunk_pass, arguments, ids, at, drive, kinds, tupled, flat)
    return at, drive, flat


#: why :func:`_drive` could not be compiled with this numba (its calling convention is not
#: the one :func:`_call_at` knows), or None: then the shares run on Python threads
_DRIVE_BROKEN: str | None = None


def _drive_ready(address: int, flat: tuple[Any, ...]) -> Any:
    """:func:`_drive`'s compiled entry for these arguments' types (compiled, or loaded, on
    first use of them; an address and a thread count are integers), which
    :func:`run_chunked` calls directly: the dispatcher's own typing of the tuple took half of
    its call (12.3 us against 6.6 us for the stage's 39 arguments, 2026-12-06), and
    :func:`_address` has already found the types the same by their kinds.  None where
    :func:`_drive` cannot be compiled: :func:`_call_at` builds its call with numba's private
    calling-convention helpers; a numba release that changed them makes the compilation fail,
    which is told once (a ``RuntimeWarning``) and answered with Python threads
    (:func:`_run_on_pool`: the same bits, more overhead a call)."""
    global _DRIVE_BROKEN
    if _DRIVE_BROKEN is not None:
        return None
    try:
        return _drive.compile((nb.typeof(address), types.int64, nb.typeof(flat)))
    except Exception as error:  # noqa: BLE001 (any failure to build the call: fall back)
        _DRIVE_BROKEN = f"{type(error).__name__}: {str(error).splitlines()[0][:200]}"
        warnings.warn(f"impactsph: the chunked passes cannot be driven on numba "
                      f"{nb.__version__}'s threads ({_DRIVE_BROKEN}); they run on Python "
                      f"threads instead (the same results, slower for small runs)",
                      RuntimeWarning, stacklevel=3)
        return None


#: the Python threads of :func:`_run_on_pool`, and how many it has
_POOL: ThreadPoolExecutor | None = None
_POOL_SIZE = 0


def _run_on_pool(chunk_pass: Callable[..., Any], threads: int, args: tuple[Any, ...]) -> None:
    """The shares on a pool of Python threads: the passes are compiled ``nogil=True``, so
    they run at once; each share is the same call as on numba's threads."""
    global _POOL, _POOL_SIZE
    if _POOL is None or _POOL_SIZE < threads:
        if _POOL is not None:
            _POOL.shutdown()
        _POOL = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="impactsph-share")
        _POOL_SIZE = threads
    futures = [_POOL.submit(chunk_pass, t, threads, *args) for t in range(threads)]
    for future in futures:
        future.result()  # (a share's exception raised here)


def numba_threads() -> int:
    """``numba.get_num_threads()``, the calling thread's count, without the lock that numba
    takes at every call to see whether its threads are started (0.66 us against 0.09 us, and
    a run asks four times a step): after the first call, which starts them, numba's own
    getter of the count (``numba.np.ufunc.parallel._get_num_threads``, private: where a
    numba release has none, the public call)."""
    global _THREAD_COUNT
    if _THREAD_COUNT is None:
        count = nb.get_num_threads()  # (starts numba's threads)
        _THREAD_COUNT = getattr(_numba_parallel, "_get_num_threads", nb.get_num_threads)
        return count
    count = _THREAD_COUNT()
    return count if count > 0 else nb.get_num_threads()  # (numba's own error)


#: numba's getter of the thread count once its threads are started (:func:`numba_threads`)
_THREAD_COUNT: Callable[[], int] | None = None


def threads_for(rows: int, chunk_size: int, threaded: bool) -> int:
    """How many shares :func:`run_chunked` runs ``rows`` rows in, in chunks of
    ``chunk_size``: numba's current thread count (``numba.set_num_threads``, which
    ``compute.threads`` sets; :func:`numba_threads`) where the passes are threaded, at most
    one a chunk; 1 for the serial passes."""
    if not threaded:
        return 1
    chunks = (rows + chunk_size - 1) // chunk_size
    return max(1, min(numba_threads(), chunks))


def run_chunked(chunk_pass: Callable[..., Any], threads: int, *args: Any) -> None:
    """``chunk_pass(t, threads, *args)`` for every share ``t = 0 .. threads - 1``: called
    directly for one, else on numba's threads (:func:`_drive`), or on Python threads where
    this numba cannot compile that (:func:`_drive_ready`); a ``chunk_pass`` that is no numba
    dispatcher (a wrapper a test or a benchmark put in its place) gets the shares one after
    another."""
    if threads <= 1:
        chunk_pass(0, 1, *args)
    elif not hasattr(chunk_pass, "overloads"):
        for t in range(threads):
            chunk_pass(t, threads, *args)
    else:
        address, drive, flat = _address(chunk_pass, args)
        if drive is not None:
            drive(address, threads, flat)
        else:
            _run_on_pool(chunk_pass, threads, args)
