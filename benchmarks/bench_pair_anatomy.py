"""Where the pair pass's time goes: the compiled pass against variants of itself, one thread.

    .venv/bin/python benchmarks/bench_pair_anatomy.py [--dims 2 3] [--n 1e5] [--rounds 3]
        [--repeat 7] [--threads 1] [--jitter 0.3]
        [--variants base self contiguous scratch no_division padded empty]

The case is ``bench_ac_cost.py``'s lattice with the paper's artificial viscosity (random
velocities of about 1 m/s). One step captures the arguments of the solver's ``pair_pass``;
each variant is the generated passes module (``impactsph.codegen``) with one edit inside
``particle_rates``, compiled in this process (no cache, so its assembly can be read), and
timed on those arguments, the variants alternating within each round so that a busy spell of
a shared machine falls on all of them. The variants change the results (except ``base``):
they are measurements of cost, nothing else.

- ``base``: the pass as the solver runs it.
- ``self``: the same code handed a list in which every neighbour index is the particle's own
  position. The loop runs the same instructions (it has no branches) and its gathers all hit
  one row in L1: what the time owes to where the neighbours lie in memory.
- ``contiguous``: the neighbours' columns read from a transposed copy (one row per column,
  made once, outside the timing) at consecutive positions ``p, p + 1, ...``: contiguous
  vector loads in place of gathers, as a cluster-pair list (GROMACS's) would give.
- ``scratch``: before each particle's loop, its neighbours' columns from the position to
  ``A`` (all but ``pc`` read by the loop) copied row by row into a scratch of one row per
  column, which the loop then reads at consecutive positions: the ``contiguous`` loop with
  the transposition paid inside the pass, particle by particle (rows of at most 256
  neighbours). The copy has no gathers (the assembly's count); it has no scatters either, as
  AVX-512's would be (not counted).
- ``no_division``: the artificial viscosity's two divisions made multiplications (the
  kernel's remain); the lattice's viscosity must be the registry's first, ``av``.
- ``padded``: the same code handed a list whose rows are padded to a multiple of 8 entries
  with a dummy record far away (no mass, no volume, another body: every sum gets exact
  zeros from it), so that no row leaves a remainder to the loop's scalar epilogue (issue 16's
  "neighbours padded in blocks of the vector width"). 1D only: in 2D and 3D the pass's skin
  filter drops the dummies before the loop.
- ``empty``: the neighbour loop removed: the per-particle part of the pass.
- ``empty_unfiltered``: ``empty`` without the skin filter: the per-particle part alone.
- ``unsplit``: 2D and 3D, each row's entries all tested against the support before the loop, as
  before the list's rows were split (``NeighbourList.splits``: the entries within the
  support at the build first, taken untested).
- ``filter_no_division``: the skin filter (:func:`support_range`) tests ``r^2 < (h_i +
  h_j)^2`` (widened by 1e-12) in place of ``q^2 < 4``, which needs ``1 / h_ij``.

``--jitter`` moves every particle by up to that fraction of the spacing in each direction,
so that the rows' lengths vary as in a run (the lattice's interior rows are all alike).

Each row gives the best time of ``--repeat`` calls in each round, the list entries per second
and, from the assembly, the vector gathers, divisions and square roots the pass contains.
"""

from __future__ import annotations

import argparse
import collections
import importlib.util
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
LOOP = "    for k in range(first, last):\n        j = listed[k]"
CALL = "            particle_rates(p, i, P, offsets, indices, visc_kind"


def _first_loop(text: str) -> tuple[int, int]:
    """The span of ``particle_rates``'s vectorised neighbour loop in the generated text."""
    start = text.index(LOOP, text.index("def particle_rates"))
    return start, text.index("    # Second loop", start)


def _edit_loop(text: str, edit) -> str:
    start, end = _first_loop(text)
    return text[:start] + edit(text[start:end]) + text[end:]


def _read_from(text: str, array: str, columns: str, position: str) -> str:
    """The neighbour loop reading ``columns`` (a regex of the record's column names) from
    ``array[column, jj]`` at ``jj = position``, not from ``P[j, column]``: ``array`` becomes
    an argument of ``particle_rates`` (passed by ``pair_pass``), and the separation helper a
    copy of the template's that reads it the same way."""
    def edit(body: str) -> str:
        # an unsigned index: numba adds no wraparound test, so LLVM sees consecutive loads
        body = body.replace("        j = listed[k]",
                            f"        j = listed[k]\n        jj = np.uint64({position})", 1)
        body = re.sub(rf"P\[j, ({columns})\]", rf"{array}[\1, jj]", body)
        return body.replace("neighbour_separation(xi0, xi1, xi2, hi, P, j)",
                            f"neighbour_separation_t(xi0, xi1, xi2, hi, {array}, jj)")
    text = _edit_loop(text, edit)
    head = "listed, starts, filter_skin):\n    \"\"\"Pass 2 for the active"
    call_end = ("listed, starts, SKIN_FILTER)\n\n\n@JIT(parallel=PARALLEL_OPTION, cache=True, "
                "error_model=BODY_ERROR_MODEL)\ndef correction_pass")
    assert head in text and call_end in text, "the template's particle_rates changed"
    text = text.replace(head, head.replace("filter_skin)", f"filter_skin, {array})"), 1)
    text = text.replace(call_end, call_end.replace("SKIN_FILTER)", f"SKIN_FILTER, {array})", 1),
                        1)
    head = text.index("def neighbour_separation(")
    helper = text[head:text.index("\n\n\n", head)]
    # the positions as float64 records hold them (the variants time float64 records: the
    # split positions of float32 ones, record_position, are not read here)
    helper = re.sub(r"neighbour_position\(P, j, (\d)\)",
                    lambda m: f"P[j, X{' + ' + m.group(1) if m.group(1) != '0' else ''}]",
                    helper)
    helper = re.sub(r"P\[j, ([^\]]+)\]", r"PT[\1, j]", helper)
    helper = helper.replace("def neighbour_separation(", "def neighbour_separation_t(")
    helper = helper.replace("hi, P, j):", "hi, PT, j):")
    return text + '\n\n@JIT(inline="always")\n' + helper + "\n"


def _contiguous(text: str) -> str:
    text = _read_from(text, "PT", r"[^\]]+", "p + k - first")
    pass_head = "chunk_size):\n    \"\"\"Pass 2 over the active particles"
    assert pass_head in text, "the template's pair_pass changed"
    return text.replace(pass_head, pass_head.replace("chunk_size)", "chunk_size, PT)"), 1)


def _scratch(text: str) -> str:
    """The neighbours' first columns (position to ``A``) copied, row by row, into a scratch of
    one row per column, which the loop then reads at consecutive positions."""
    copy = """    n_read = A0 + DIM * (DIM + 1) // 2
    for kk in range(last - first):
        jc = listed[first + kk]
        for c in range(n_read):
            Q[c, kk] = P[jc, c]
"""
    text = _edit_loop(text, lambda body: body.replace(LOOP, copy + LOOP, 1))
    text = _read_from(text, "Q", r"(?:X|V|H|M|VOL|RHO|C|BODY|A\d\d)(?: \+ \d)?",
                      "k - first")
    scratch = "        L = np.empty((DIM, DIM))  # scratch: the velocity gradient of one particle"
    rows = "\n        Q = np.empty((A0 + DIM * (DIM + 1) // 2, 256))"
    return text.replace(scratch, scratch + rows, 1)


FILTER = """                q2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)[6]
                listed[count] = j
                count += 1 if q2 < 4.0 else 0"""


def _filter_no_division(text: str) -> str:
    """The skin filter's support test without its division: ``r^2 < (h_i + h_j)^2``
    (``q < 2`` with ``h_ij = (h_i + h_j) / 2``), a margin of 1e-12 wide so that it keeps
    every pair the loop's own test keeps (the loop masks the rest)."""
    test = """                r2 = neighbour_separation(xi0, xi1, xi2, hi, P, j)[3]
                reach = hi + P[j, H]
                listed[count] = j
                count += 1 if r2 < reach * reach * (1.0 + 1e-12) else 0"""
    assert FILTER in text
    return text.replace(FILTER, test, 1)


def _empty(text: str) -> str:
    return _edit_loop(text, lambda b: b.replace("range(first, last)",
                                                "range(first, first)", 1))


def _empty_unfiltered(text: str) -> str:
    """``empty`` without the skin filter too: the per-particle part alone."""
    assert FILTER in text
    return _empty(text.replace("        if filter_skin:", "        if False:", 1))


#: (``self``, ``padded`` and ``unsplit`` edit the list they are handed, ``no_division`` the
#: viscosity injected: not the text)
VARIANTS = {"base": lambda t: t, "self": lambda t: t, "contiguous": _contiguous,
            "scratch": _scratch, "no_division": lambda t: t, "padded": lambda t: t,
            "empty": _empty, "filter_no_division": _filter_no_division,
            "empty_unfiltered": _empty_unfiltered, "unsplit": lambda t: t}
#: the block that ``padded`` pads each row to
PAD_BLOCK = 8


def _padded(record, offsets, indices, columns: dict[str, int], dim: int, block: int = PAD_BLOCK):
    """``record`` with a dummy row appended (far away, no mass or volume, body -1) and the
    list's rows padded with that row's index to a multiple of ``block`` entries."""
    import numpy as np

    n = record.shape[0]
    dummy = np.zeros((1, record.shape[1]))
    dummy[0, columns["X"]:columns["X"] + dim] = 1e30
    dummy[0, columns["H"]] = record[0, columns["H"]]
    dummy[0, columns["RHO"]] = 1.0
    dummy[0, columns["BODY"]] = -1.0
    rows = np.diff(offsets)
    padded_rows = (rows + block - 1) // block * block
    new_offsets = np.zeros_like(offsets)
    new_offsets[1:] = np.cumsum(padded_rows)
    new_indices = np.full(int(new_offsets[-1]), n, dtype=indices.dtype)
    within = np.arange(new_indices.shape[0]) - np.repeat(new_offsets[:-1], padded_rows)
    keep = within < np.repeat(rows, padded_rows)
    new_indices[keep] = indices
    return np.vstack([record, dummy]), new_offsets, new_indices


def _injected(name: str, inject: dict) -> dict:
    if name != "no_division":
        return inject
    import numba as nb

    @nb.njit(inline="always")
    def viscosity(vr, r2, h_ij, c_ij, rho_ij, params):
        mu = h_ij * min(vr, 0.0) * (r2 + params[2] * h_ij * h_ij)
        return (-params[0] * c_ij * mu + params[1] * mu * mu) * rho_ij

    return {**inject, "_viscosity_0": viscosity}


def _load(name: str, text: str, inject: dict, folder: Path):
    text = VARIANTS[name](text).replace("cache=True", "cache=False")
    path = folder / f"anatomy_{name}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(f"anatomy_{name}", path)
    module = importlib.util.module_from_spec(spec)
    module.__dict__.update(_injected(name, inject))
    sys.modules[spec.name] = module
    exec(compile(text, str(path), "exec"), module.__dict__)
    return module


def _assembly_counts(function) -> dict[str, int]:
    asm = "\n".join(function.inspect_asm().values())
    ops = collections.Counter(line.split()[0] for line in asm.splitlines()
                              if line.startswith("\t") and line.split())
    return {"gathers": ops["vgatherqpd"] + ops["vgatherdpd"],
            "divisions": ops["vdivpd"], "square roots": ops["vsqrtpd"]}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dims", type=int, nargs="+", default=[2, 3], choices=(1, 2, 3))
    parser.add_argument("--n", type=float, default=1e5, help="target particle count")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--jitter", type=float, default=0.0,
                        help="move each particle by up to this fraction of the spacing")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = parser.parse_args(argv)

    import numba as nb
    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_ac_cost import lattice_case

    from impactsph.integrate import stable_time_step
    from impactsph.loading import validate_case
    from impactsph.physics.chunked import run_chunked
    from impactsph.simulation import Simulation

    folder = Path(tempfile.mkdtemp(prefix="impactsph-anatomy-"))
    for dim in args.dims:
        sim = Simulation(validate_case(lattice_case(dim, int(args.n), "av")))
        rng = np.random.default_rng(1)
        sim.state.velocity[:] = rng.normal(size=sim.state.velocity.shape)
        if args.jitter:
            spacing = float(sim.state.smoothing_length[0]) / sim.case.kernel.h_over_dx
            sim.state.position[:] += args.jitter * spacing * rng.uniform(
                -1.0, 1.0, size=sim.state.position.shape)
        dt = 0.1 * stable_time_step(sim.state, sim.problem.table, 0.3)
        # the module whose pair pass runs this lattice: its h are all the same, so the loops
        # of one smoothing length (CpuRates.neighbour_loops, since 2026-12-04)
        backend = sim.solver.backend
        passes = (backend.neighbour_loops(True) if hasattr(backend, "neighbour_loops")
                  else backend.passes)
        captured = {}
        solver_pass = passes.pair_pass

        def grab(*a, _captured=captured, _solver_pass=solver_pass):
            if a[0] == 0:  # the first thread's call, as one call over every chunk
                _captured["args"] = (0, 1, *a[2:])
            return _solver_pass(*a)

        passes.pair_pass = grab
        sim.integrator.step(sim.state, dt)
        passes.pair_pass = solver_pass
        call = list(captured["args"])
        record = call[4]
        transposed = np.zeros((record.shape[1], record.shape[0] + 256))
        transposed[:, :record.shape[0]] = record.T
        entries = int(call[6].shape[0])
        offsets = call[5]
        if int(np.diff(offsets).max()) > 256:  # the scratch's rows; PT's padding
            sys.exit("bench_pair_anatomy: a neighbour row is longer than 256")
        if "no_division" in args.variants and int(call[8]) != 0:
            sys.exit("bench_pair_anatomy: no_division replaces viscosity 0, not this case's")
        own = np.repeat(np.arange(offsets.shape[0] - 1, dtype=call[6].dtype), np.diff(offsets))
        variants = [v for v in args.variants if v != "padded" or dim < 2]
        padded = []
        if "padded" in variants:
            columns = {c: int(getattr(passes, c)) for c in ("X", "H", "RHO", "BODY")}
            padded = list(_padded(record, offsets, call[6], columns, dim))
            padded.append(padded[1][:-1])  # (its starts: 1D does not read them)

        def arguments(name, _call=call, _own=own, _transposed=transposed, _padded_=padded):
            if name == "self":
                return _call[:6] + [_own] + _call[7:]
            if name == "padded":
                return _call[:4] + _padded_ + _call[8:]
            if name == "unsplit":  # every row tested from its start
                return _call[:7] + [_call[5][:-1]] + _call[8:]
            return _call + [_transposed] if name == "contiguous" else _call

        text = Path(passes.__file__).read_text()
        inject = {k: v for k, v in vars(passes).items()
                  if k.startswith("_") and hasattr(v, "py_func")}
        nb.set_num_threads(args.threads)
        modules, counts, best = {}, {}, collections.defaultdict(list)
        for name in variants:
            modules[name] = _load(name, text, inject, folder)
            modules[name].pair_pass(*arguments(name))  # compiles
            counts[name] = _assembly_counts(modules[name].pair_pass)
        for _ in range(args.rounds):
            for name in variants:
                function, given = modules[name].pair_pass, arguments(name)
                times = []
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    run_chunked(function, args.threads, *given[2:])  # (given: 0, 1, ...)
                    times.append(time.perf_counter() - t0)
                best[name].append(min(times))
        print(f"\n{dim}D, {record.shape[0]} particles, {entries} list entries, "
              f"{args.threads} thread(s), best of {args.repeat} in each of {args.rounds} rounds")
        print(f"{'variant':<12} {'ms per round':<30} {'entries/s (best)':>16} {'/ base':>7} "
              f"{'gathers':>7} {'vdivpd':>6} {'vsqrtpd':>7}")
        base = min(best["base"]) if "base" in best else None
        for name in variants:
            ms = " ".join(f"{t * 1e3:.1f}" for t in best[name])
            ratio = f"{min(best[name]) / base:7.2f}" if base else f"{'':7}"
            c = counts[name]
            print(f"{name:<12} {ms:<30} {entries / min(best[name]):16.3e} {ratio} "
                  f"{c['gathers']:7d} {c['divisions']:6d} {c['square roots']:7d}")
        for name in list(sys.modules):
            if name.startswith("anatomy_"):
                del sys.modules[name]


if __name__ == "__main__":
    main()
