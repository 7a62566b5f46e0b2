"""The chunked passes' runner (:mod:`impactsph.physics.chunked`): every chunk once, in shares
on numba's threads, the pass called at its address; and a compiled chunked pass gives the
same bits on one thread and on several."""

from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from impactsph.physics.chunked import run_chunked, threads_for


@nb.njit(nogil=True)
def _count_chunks(first, step, seen, shares):
    chunks = seen.shape[0]
    shares[first] += step  # each share once, told the share count
    for chunk in range(first * chunks // step, (first + 1) * chunks // step):
        seen[chunk] += 1


def test_each_share_runs_once_and_the_chunks_are_covered_once():
    for threads in (1, 2, 3):
        seen, shares = np.zeros(11, dtype=np.int64), np.zeros(3, dtype=np.int64)
        run_chunked(_count_chunks, threads, seen, shares)
        assert seen.tolist() == [1] * 11, threads
        assert shares.tolist() == [threads] * threads + [0] * (3 - threads), threads


def test_threads_for_takes_numbas_count_at_most_one_a_chunk_and_one_serial(monkeypatch):
    from impactsph.physics import chunked

    monkeypatch.setattr(chunked, "numba_threads", lambda: 4)
    assert threads_for(1000, 100, True) == 4
    assert threads_for(250, 100, True) == 3  # three chunks
    assert threads_for(10, 100, True) == 1
    assert threads_for(1000, 100, False) == 1  # the serial passes


def test_numba_threads_is_numbas_count_as_it_is_set():
    """The count without numba's lock is numba's own, before its threads start and after,
    as ``numba.set_num_threads`` changes it."""
    from impactsph.physics import chunked

    assert chunked.numba_threads() == nb.get_num_threads()
    assert chunked._THREAD_COUNT is not None
    before = nb.get_num_threads()
    try:
        for count in sorted({1, nb.config.NUMBA_NUM_THREADS}):
            nb.set_num_threads(count)
            assert chunked.numba_threads() == count == nb.get_num_threads()
    finally:
        nb.set_num_threads(before)


@nb.njit(inline="always")
def _share_rows(first, step, n, chunk_size):
    """The rows of share ``first`` of ``step``: its block of consecutive chunks."""
    chunks = (n + chunk_size - 1) // chunk_size
    return (first * chunks // step) * chunk_size, min(((first + 1) * chunks // step)
                                                      * chunk_size, n)


@nb.njit(nogil=True, fastmath={"reassoc", "arcp", "nsz"})
def _row_sums(first, step, values, out, chunk_size):
    lo, hi = _share_rows(first, step, values.shape[0], chunk_size)
    for i in range(lo, hi):
        s = 0.0
        for k in range(values.shape[1]):
            s += values[i, k]
        out[i] = s


def test_a_compiled_chunked_pass_gives_the_same_bits_in_any_number_of_shares():
    values = np.random.default_rng(3).normal(size=(997, 61))
    outs = []
    for threads in (1, 2, 3):
        out = np.full(997, np.nan)
        run_chunked(_row_sums, threads, values, out, 16)
        outs.append(out)
    assert not np.isnan(outs[0]).any()
    assert outs[0].tobytes() == outs[1].tobytes() == outs[2].tobytes()
    # a new array of another type: the pass compiled again for it, at another address
    out32 = np.full(997, np.nan, dtype=np.float32)
    run_chunked(_row_sums, 2, values, out32, 16)
    assert np.allclose(out32, outs[0], rtol=1e-6)
    assert len(_row_sums.overloads) == 2


def test_a_numba_that_cannot_build_the_drive_gets_python_threads_and_one_warning(monkeypatch):
    """``_call_at`` uses numba's private calling-convention helpers; where a numba release
    has changed them, the compilation of ``_drive`` fails, and the shares must still run, on
    Python threads, to the same bits, with one warning that says so."""
    from impactsph.physics import chunked

    class _Unbuildable:
        def compile(self, signature):
            raise AttributeError("'CPUCallConv' object has no attribute '_get_arg_packer'")

        def __call__(self, *args):
            raise AssertionError("the drive must not run where it could not be compiled")

    values = np.random.default_rng(5).normal(size=(501, 37))
    serial = np.full(501, np.nan)
    run_chunked(_row_sums, 1, values, serial, 16)
    monkeypatch.setattr(chunked, "_drive", _Unbuildable())
    monkeypatch.setattr(chunked, "_DRIVE_BROKEN", None)
    monkeypatch.setattr(chunked, "_ADDRESSES", {})
    outs = []
    with pytest.warns(RuntimeWarning, match="Python threads") as caught:
        for threads in (2, 3, 2):
            out = np.full(501, np.nan)
            run_chunked(_row_sums, threads, values, out, 16)
            outs.append(out)
    assert len(caught) == 1  # told once
    assert "_get_arg_packer" in chunked._DRIVE_BROKEN
    for out in outs:
        assert out.tobytes() == serial.tobytes()


def test_a_pass_is_looked_up_once_for_its_arguments_kinds(monkeypatch):
    """The address and the drive are looked up once for the kinds of a pass's arguments: a
    new Python number (``float(elapsed)`` is a new object each call) does not look them up
    again, nor a new array or a new view of the same dtype, dimensions, layout and
    writeability (a 1D run's row starts, ``offsets[:-1]``, are a new view at each
    evaluation); an array of another kind does, and runs with its own code."""
    from impactsph.physics import chunked

    lookups = []
    ready = chunked._drive_ready
    monkeypatch.setattr(chunked, "_ADDRESSES", {})
    monkeypatch.setattr(chunked, "_drive_ready",
                        lambda *a: lookups.append(1) or ready(*a))
    values = np.random.default_rng(6).normal(size=(301, 7))
    out = np.empty(301)
    for chunk_size in (16, 17, 16):  # a new int object's value, the same arrays
        out[:] = np.nan
        run_chunked(_row_sums, 2, values, out, chunk_size)
        assert np.allclose(out, values.sum(axis=1), rtol=1e-14, atol=0.0)
    assert len(lookups) == 1
    run_chunked(_row_sums, 2, values.copy(), np.empty(301), 16)  # new arrays, same kinds
    whole = np.empty(302)
    run_chunked(_row_sums, 2, values, whole[:-1], 16)  # a new view, the same kind
    assert len(lookups) == 1
    assert np.allclose(whole[:-1], values.sum(axis=1), rtol=1e-14, atol=0.0)
    strided = np.full(602, np.nan)
    run_chunked(_row_sums, 2, values, strided[::2], 16)  # not contiguous: another kind
    assert len(lookups) == 2
    assert np.allclose(strided[::2], values.sum(axis=1), rtol=1e-14, atol=0.0)
    assert np.isnan(strided[1::2]).all()
    frozen = values.copy()
    frozen.flags.writeable = False  # read-only: another numba type, so another kind
    run_chunked(_row_sums, 2, frozen, out, 16)
    assert len(lookups) == 3
    assert chunked._kinds((values, out)) != chunked._kinds((frozen, out))
    assert chunked._kinds((values, out)) != chunked._kinds((values.astype(np.float32), out))
    # a tuple by its elements' kinds: a new tuple of the same kinds is the same kind
    assert chunked._kinds(((0.3, 0.4), 2)) == chunked._kinds(((0.5, 0.6), 3))
    assert chunked._kinds(((0.3, 0.4), 2)) != chunked._kinds(((0.3, 4), 2))
    assert chunked._kinds(((0.3, 0.4),)) != chunked._kinds(((0.3, 0.4, 0.5),))
    # the layout as numba reads it: an array of one column (C- and F-contiguous both) is of
    # the kind of any C-contiguous one, as numba types it; F and strided ones are not
    shapes = [np.zeros((2, 1)), np.zeros((2, 3)), np.zeros((3, 2)).T, np.zeros((4, 4))[:, ::2],
              np.zeros((1, 3)), np.zeros((0, 3))]
    for a in shapes:
        for b in shapes:
            assert (chunked._kind(a) == chunked._kind(b)) == (nb.typeof(a) == nb.typeof(b))
    assert chunked._DRIVE_BROKEN is None
    signature = (nb.int64, nb.int64, nb.typeof(chunked._flat((values, out, 16))))
    assert sum(tuple(s) == signature for s in chunked._drive.overloads) == 1


@nb.njit(nogil=True)
def _weighted_row_sums(first, step, values, weights, scale, out, chunk_size):
    lo, hi = _share_rows(first, step, values.shape[0], chunk_size)
    for i in range(lo, hi):
        total = 0.0
        for k in range(values.shape[1]):
            total += weights[k] * values[i, k]
        out[i] = scale * total


def test_a_tupled_pass_splices_its_arguments_again_only_where_one_changed(monkeypatch):
    """A pass with a tuple among its arguments (the pair pass's viscosity parameters) has
    them spliced (:func:`impactsph.physics.chunked._flat`) at its first call and again only
    where an argument is another object or number than the last call's: the same arguments
    reuse the last splice, and a new number or a new tuple gives its own result at once."""
    from impactsph.physics import chunked

    spliced = []
    flat = chunked._flat
    monkeypatch.setattr(chunked, "_ADDRESSES", {})
    monkeypatch.setattr(chunked, "_flat", lambda a: spliced.append(1) or flat(a))
    values = np.random.default_rng(8).normal(size=(301, 3))
    out = np.empty(301)
    weights = (1.0, 2.0, 3.0)

    def expected(w, scale):
        return scale * (values @ np.array(w))

    for _ in range(3):  # the same objects and numbers: one splice
        out[:] = np.nan
        run_chunked(_weighted_row_sums, 2, values, weights, 0.5, out, 16)
        assert np.allclose(out, expected(weights, 0.5), rtol=1e-14, atol=0.0)
    assert len(spliced) == 1
    run_chunked(_weighted_row_sums, 2, values, weights, 2.0, out, 16)  # another number
    assert np.allclose(out, expected(weights, 2.0), rtol=1e-14, atol=0.0)
    assert len(spliced) == 2
    run_chunked(_weighted_row_sums, 2, values, weights, 2.0, out, 16)
    assert len(spliced) == 2
    other = (3.0, -1.0, 0.25)  # another tuple of the same kind
    run_chunked(_weighted_row_sums, 2, values, other, 2.0, out, 16)
    assert np.allclose(out, expected(other, 2.0), rtol=1e-14, atol=0.0)
    fresh = np.empty(301)  # another array of the same kind
    run_chunked(_weighted_row_sums, 2, values, other, 2.0, fresh, 16)
    assert np.allclose(fresh, expected(other, 2.0), rtol=1e-14, atol=0.0)
    assert len(spliced) == 4


def test_a_run_types_its_pass_arguments_once(monkeypatch):
    """A run's chunked pass is typed (``numba.typeof`` of its arguments and the drive's tuple,
    some 0.6 ms) once, not at each evaluation: its arrays keep their kinds from one list
    build to the next.  A 1D list's row starts were a new view at every evaluation, and the
    bars spent 77% of their run typing them (benchmarks/README.md, "The chunked passes'
    lookup").  The test suite's serial passes run in one share, so the shares are asked for
    here; the run's state is the one share's to the bit."""
    from impactsph import Simulation, load_case
    from impactsph.physics import chunked, rates

    case = load_case("bars", ["time.max_steps=40"])
    alone = Simulation(case)
    alone.run()
    typed, looked_up = [], []
    ready, address = chunked._drive_ready, chunked._address
    monkeypatch.setattr(chunked, "_ADDRESSES", {})
    monkeypatch.setattr(chunked, "_drive_ready",
                        lambda *a: typed.append(looked_up[-1]) or ready(*a))
    monkeypatch.setattr(chunked, "_address",
                        lambda p, a: looked_up.append(p.__name__) or address(p, a))
    monkeypatch.setattr(rates, "threads_for", lambda rows, chunk, threaded: 2)
    shared = Simulation(case)
    shared.run()
    assert shared.solver.neighbours.builds > 1  # new lists came, of the same kinds
    # (each pass typed once: the pair pass, and the list build's sweep where numba has
    # threads for it, as with -n 0; pytest-xdist's workers run one thread, one share)
    assert looked_up.count("pair_pass") > 80 and typed.count("pair_pass") == 1, (
        looked_up.count("pair_pass"), typed)
    assert len(typed) == len(set(typed)), typed
    for name, value in alone.state.arrays().items():
        assert np.asarray(value).tobytes() == np.asarray(shared.state.arrays()[name]).tobytes()


def test_a_midpoint_step_hands_its_stages_the_same_arrays(monkeypatch):
    """The midpoint step's two stages hand the stage pass the same arrays (the positions'
    rate is the state's own velocity in both), so that after its first call the pass is
    found by its arguments' identities alone: the predictor's rate was the start copy's
    velocity, and each stage looked the pass up by the kinds of its 39 arguments (some 12 us
    a call, where the identities take 3). Run in two shares; the state is the one share's to
    the bit."""
    from impactsph import Simulation, integrate, load_case
    from impactsph.physics import chunked

    case = load_case("taylor", ["time.max_steps=30", "output.figures=false"])
    alone = Simulation(case)
    alone.run()
    calls, kinds = [], []
    address, find_kinds = chunked._address, chunked._kinds
    monkeypatch.setattr(chunked, "_ADDRESSES", {})
    monkeypatch.setattr(chunked, "_address",
                        lambda p, a: calls.append(p.__name__) or address(p, a))
    monkeypatch.setattr(chunked, "_kinds",
                        lambda a: kinds.append(calls[-1]) or find_kinds(a))
    monkeypatch.setattr(integrate, "threads_for", lambda rows, chunk, threaded: 2)
    shared = Simulation(case)
    shared.run()
    assert calls.count("stage") == 2 * shared.state.step
    # looked up by kinds at its first call and where a list build gave the state new arrays
    # (the ghosts' rows: Solver._allocate), not at each stage (the tree before: 60 of 60)
    builds = shared.solver.neighbours.builds
    assert kinds.count("stage") <= 1 + builds < shared.state.step, (kinds.count("stage"), builds)
    for name, value in alone.state.arrays().items():
        assert np.asarray(value).tobytes() == np.asarray(shared.state.arrays()[name]).tobytes()
