"""What the naive yardstick's 2D pair arithmetic reaches on this machine as a bare vectorised
loop over a list built once, beside the yardstick and impactsph, in one process (issue 16's
pair-rate targets).

    .venv/bin/python benchmarks/bench_bare_loop.py [--side 316] [--threads 1 2] [--rounds 5]

Every kernel here evaluates the equations of the naive yardstick
(``../shared/bench/naive_pairs.py``: the paper's 2D momentum, continuity and energy sums with
Monaghan's artificial viscosity, the velocity gradient, the cubic spline of one smoothing
length) on its lattice (``--side`` squared particles, h = 1.3 dx, jittered by 5% of dx):

* ``naive``: the yardstick itself, imported from ``--naive`` (cell list rebuilt and scanned
  at every evaluation, as its own ``main`` times it), where that file exists;
* ``bare``: the same sums over a neighbour list built once (CSR, every ordered pair within
  the support, rows in the lattice's order), with no branch in the loop, the zero-division
  checks off and reassociation allowed (impactsph's pair flags, ``PAIR_FASTMATH``), so that
  LLVM vectorises it; nothing before or after the loop but loading the particle's own
  values and storing its eight sums. No list update, no particle pass, no stress rate, no
  survey: what a rate evaluation with this arithmetic could reach here if it were the pair
  loop alone (not a bound on every arithmetic: fewer operations a pair, float32 lanes or
  512-bit vectors could pass it);
* ``half``: the symmetric (half) list, each pair once (j > i), the neighbour's share added
  into a per-thread buffer by a scalar read-modify-write (then summed over the threads);
* ``half_scratch``: the same, the neighbour's shares first stored in a contiguous scratch
  (so that the pair loop can vectorise), then added in a second, scalar loop;
* ``impactsph``: one rate evaluation of ``bench_rates.py``'s 2D lattice of the same size
  (``sim.solver.rates``: the list's displacement check, the particle pass, the pair pass and
  its per-particle part; h = 1.2 dx, 19.9 pairs a particle as here), and its pair pass alone.

A pair evaluation is one ordered pair (i, j) within the support, so a half list's pair counts
twice. Each kernel's eight sums are checked against ``bare``'s (largest relative
difference over the lattice); the rounds alternate the kernels and the best round is kept.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

import impactsph  # noqa: F401  (before the first njit below: the vectors' width, impactsph.vectors)

HERE = Path(__file__).resolve().parent
NAIVE = HERE.parent.parent / "shared" / "bench" / "naive_pairs.py"
#: impactsph's flags for its pair loops (physics/passes.py, PAIR_FASTMATH)
FLAGS = {"reassoc", "arcp", "nsz", "contract"}
SUMS = 8  # ax, ay, drho, de, and the velocity gradient's four components


@njit(cache=True)
def build_list(x, y, reach):  # pragma: no cover (benchmark)
    """Every ordered pair within ``reach``: CSR offsets and neighbour indices (int32)."""
    n = x.size
    xmin, ymin = x.min(), y.min()
    ncx = int((x.max() - xmin) / reach) + 1
    ncy = int((y.max() - ymin) / reach) + 1
    cell = np.empty(n, np.int64)
    for i in range(n):
        cell[i] = int((y[i] - ymin) / reach) * ncx + int((x[i] - xmin) / reach)
    order = np.argsort(cell)
    start = np.zeros(ncx * ncy + 1, np.int64)
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(ncx * ncy):
        start[c + 1] += start[c]
    offsets = np.zeros(n + 1, np.int64)
    found = np.empty(n * 40, np.int32)
    k = 0
    for i in range(n):
        cx, cy = cell[i] % ncx, cell[i] // ncx
        offsets[i] = k
        for yy in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for xx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                for jj in range(start[yy * ncx + xx], start[yy * ncx + xx + 1]):
                    j = order[jj]
                    if j != i and (x[i] - x[j]) ** 2 + (y[i] - y[j]) ** 2 < reach * reach:
                        found[k] = j
                        k += 1
    offsets[n] = k
    return offsets, found[:k].copy()


@njit(cache=True)
def halve(offsets, neighbours):  # pragma: no cover (benchmark)
    """The half list: each row's neighbours j > i."""
    n = offsets.size - 1
    half_offsets = np.zeros(n + 1, np.int64)
    for i in range(n):
        c = 0
        for k in range(offsets[i], offsets[i + 1]):
            c += neighbours[k] > i
        half_offsets[i + 1] = half_offsets[i] + c
    half = np.empty(half_offsets[n], np.int32)
    for i in range(n):
        p = half_offsets[i]
        for k in range(offsets[i], offsets[i + 1]):
            if neighbours[k] > i:
                half[p] = neighbours[k]
                p += 1
    return half_offsets, half


@njit(inline="always")
def _pair(xi, yi, vxi, vyi, ci, rhoi, h, ad, x, y, vx, vy, c, rho, j):  # pragma: no cover
    """The pair's kernel gradient (wx, wy), velocity difference, Pi_ij and r2, branch-free."""
    rx = xi - x[j]
    ry = yi - y[j]
    r2 = rx * rx + ry * ry
    r = math.sqrt(r2)
    q = r / h
    near = ad * (-3.0 * q + 2.25 * q * q) / h
    far = -ad * 0.75 * (2.0 - q) ** 2 / h
    dw = near if q < 1.0 else far
    dw = dw if q < 2.0 else 0.0
    f = dw / (r + 1e-30)
    vxij = vxi - vx[j]
    vyij = vyi - vy[j]
    mu = h * min(vxij * rx + vyij * ry, 0.0) / (r2 + 0.01 * h * h)
    visc = (-0.5 * (ci + c[j]) * mu + mu * mu) / (0.5 * (rhoi + rho[j]))
    return f * rx, f * ry, vxij, vyij, visc


@njit(inline="always")
def _own_terms(mj, vj, fx, fy, dvw, vxij, vyij, wx, wy, visc, sixx, sixy,
               siyy):  # pragma: no cover (benchmark)
    """The pair's terms of the particle's eight sums (``fx, fy``: ``(A_i + A_j + Pi_ij I) .
    grad W_ij``)."""
    return (-mj * fx, -mj * fy, vj * dvw,
            mj * (vxij * (sixx * wx + sixy * wy) + vyij * (sixy * wx + siyy * wy)
                  + 0.5 * visc * dvw),
            -vj * vxij * wx, -vj * vxij * wy, -vj * vyij * wx, -vj * vyij * wy)


@njit(parallel=True, fastmath=FLAGS, error_model="numpy", cache=True)
def bare(x, y, vx, vy, rho, m, p, sxx, sxy, syy, c, h, offsets, neighbours,
            out):  # pragma: no cover (benchmark)
    """The full list, vectorised: one row's eight sums a particle."""
    ad = 10.0 / (7.0 * np.pi * h * h)
    for i in prange(x.size):
        inv2 = 1.0 / (rho[i] * rho[i])
        sixx, sixy, siyy = (p[i] - sxx[i]) * inv2, -sxy[i] * inv2, (p[i] - syy[i]) * inv2
        xi, yi, vxi, vyi, ci, rhoi = x[i], y[i], vx[i], vy[i], c[i], rho[i]
        axi = ayi = dr = dei = g0 = g1 = g2 = g3 = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = neighbours[k]
            wx, wy, vxij, vyij, visc = _pair(xi, yi, vxi, vyi, ci, rhoi, h, ad, x, y, vx, vy,
                                             c, rho, j)
            invj = 1.0 / (rho[j] * rho[j])
            txx = sixx + (p[j] - sxx[j]) * invj + visc
            txy = sixy - sxy[j] * invj
            tyy = siyy + (p[j] - syy[j]) * invj + visc
            mj = m[j]
            terms = _own_terms(mj, mj / rho[j], txx * wx + txy * wy, txy * wx + tyy * wy,
                               vxij * wx + vyij * wy, vxij, vyij, wx, wy, visc, sixx, sixy,
                               siyy)
            axi += terms[0]
            ayi += terms[1]
            dr += terms[2]
            dei += terms[3]
            g0 += terms[4]
            g1 += terms[5]
            g2 += terms[6]
            g3 += terms[7]
        out[0, i] = axi
        out[1, i] = ayi
        out[2, i] = rhoi * dr
        out[3, i] = dei
        out[4, i] = g0
        out[5, i] = g1
        out[6, i] = g2
        out[7, i] = g3


@njit(inline="always")
def _half_row(i, x, y, vx, vy, rho, m, p, sxx, sxy, syy, c, h, ad, offsets, neighbours,
              into, scratch):  # pragma: no cover (benchmark)
    """Row i of the half list: its own sums into ``into[:, i]``; the neighbours' shares
    straight into ``into[:, j]`` (``scratch`` empty) or through ``scratch``."""
    inv2 = 1.0 / (rho[i] * rho[i])
    sixx, sixy, siyy = (p[i] - sxx[i]) * inv2, -sxy[i] * inv2, (p[i] - syy[i]) * inv2
    xi, yi, vxi, vyi, ci, rhoi, mi = x[i], y[i], vx[i], vy[i], c[i], rho[i], m[i]
    vi = mi / rhoi
    axi = ayi = dr = dei = g0 = g1 = g2 = g3 = 0.0
    direct = scratch.shape[0] == 0
    first = offsets[i]
    for k in range(first, offsets[i + 1]):
        j = neighbours[k]
        wx, wy, vxij, vyij, visc = _pair(xi, yi, vxi, vyi, ci, rhoi, h, ad, x, y, vx, vy, c,
                                         rho, j)
        invj = 1.0 / (rho[j] * rho[j])
        sjxx, sjxy, sjyy = (p[j] - sxx[j]) * invj, -sxy[j] * invj, (p[j] - syy[j]) * invj
        fx = (sixx + sjxx + visc) * wx + (sixy + sjxy) * wy
        fy = (sixy + sjxy) * wx + (siyy + sjyy + visc) * wy
        dvw = vxij * wx + vyij * wy
        terms = _own_terms(m[j], m[j] / rho[j], fx, fy, dvw, vxij, vyij, wx, wy, visc, sixx,
                           sixy, siyy)
        axi += terms[0]
        ayi += terms[1]
        dr += terms[2]
        dei += terms[3]
        g0 += terms[4]
        g1 += terms[5]
        g2 += terms[6]
        g3 += terms[7]
        # j's share: grad_j W_ji = -grad_i W_ij and v_ji = -v_ij
        share = (mi * fx, mi * fy, vi * dvw,
                 mi * (vxij * (sjxx * wx + sjxy * wy) + vyij * (sjxy * wx + sjyy * wy)
                       + 0.5 * visc * dvw),
                 -vi * vxij * wx, -vi * vxij * wy, -vi * vyij * wx, -vi * vyij * wy)
        if direct:
            for f in range(SUMS):
                into[f, j] += share[f]
        else:
            for f in range(SUMS):
                scratch[k - first, f] = share[f]
    if not direct:
        for k in range(first, offsets[i + 1]):
            j = neighbours[k]
            for f in range(SUMS):
                into[f, j] += scratch[k - first, f]
    into[0, i] += axi
    into[1, i] += ayi
    into[2, i] += dr
    into[3, i] += dei
    into[4, i] += g0
    into[5, i] += g1
    into[6, i] += g2
    into[7, i] += g3


@njit(parallel=True, fastmath=FLAGS, error_model="numpy", cache=True)
def half(x, y, vx, vy, rho, m, p, sxx, sxy, syy, c, h, offsets, neighbours, buffers,
         scratch, out):  # pragma: no cover (benchmark)
    """The half list: ``buffers[t]`` a thread's sums (its rows a contiguous block), then
    their sum; ``scratch[t]`` (rows x 8) for the scratch variant, or of no rows."""
    n = x.size
    threads = buffers.shape[0]
    ad = 10.0 / (7.0 * np.pi * h * h)
    for t in prange(threads):
        into = buffers[t]
        into[:, :] = 0.0
        for i in range((n * t) // threads, (n * (t + 1)) // threads):
            _half_row(i, x, y, vx, vy, rho, m, p, sxx, sxy, syy, c, h, ad, offsets,
                      neighbours, into, scratch[t])
    for i in prange(n):
        for f in range(SUMS):
            total = 0.0
            for t in range(threads):
                total += buffers[t, f, i]
            out[f, i] = total
        out[2, i] *= rho[i]


def lattice(side: int) -> tuple:
    """The naive yardstick's lattice and fields (its own construction, a fixed seed)."""
    dx = 1.0 / side
    h = 1.3 * dx
    g = (np.arange(side) + 0.5) * dx
    gx, gy = np.meshgrid(g, g)
    rng = np.random.default_rng(20261206)
    x = gx.ravel() + 0.05 * dx * rng.random(side * side)
    y = gy.ravel() + 0.05 * dx * rng.random(side * side)
    n = x.size
    fields = dict(x=x, y=y, vx=rng.random(n), vy=rng.random(n), rho=7850 + rng.random(n),
                  m=np.full(n, 7850 * dx * dx), p=rng.random(n), sxx=rng.random(n),
                  sxy=rng.random(n), syy=rng.random(n), c=np.full(n, 5000.0))
    return fields, h


def load_naive(path: Path):
    """The yardstick's module (its ``main`` runs for its own argv only: none here)."""
    argv, sys.argv = sys.argv, [str(path)]
    try:
        spec = importlib.util.spec_from_file_location("naive_pairs", path)
        module = importlib.util.module_from_spec(spec)
        # registered before it runs: numba's cache finds a cached function's module by name
        # when it loads it (unregistered, a second process's load failed: "No module named
        # '<dynamic>'")
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
    finally:
        sys.argv = argv
    return module


def impactsph_rates(side: int):
    """bench_rates.py's 2D lattice of ``side``^2 particles: (rates, pair pass alone, pairs)."""
    sys.path.insert(0, str(HERE))
    from bench_rates import make_case

    from impactsph.loading import validate_case
    from impactsph.simulation import Simulation

    sim = Simulation(validate_case(make_case(side * side, 2)))
    state = sim.state
    state.velocity[:] = np.random.default_rng(1).normal(0.0, 1.0, size=state.velocity.shape)
    # the pair pass timed where the rates hand it to run_chunked (a wrapper in the pass's
    # place would run its shares one after another: run_chunked's docstring)
    from impactsph.physics import rates as rates_module
    pair_times: list[float] = []
    run_chunked = rates_module.run_chunked

    def timed(chunk_pass, *args):
        t0 = time.perf_counter()
        run_chunked(chunk_pass, *args)
        if getattr(chunk_pass, "__name__", "") == "pair_pass":
            pair_times.append(time.perf_counter() - t0)
    rates_module.run_chunked = timed
    sim.solver.rates(state)
    pairs = int(sim.solver.buffers.pair_count[: state.n].sum())

    def rates() -> None:
        sim.solver.rates(state)

    def pair_pass_last() -> float:
        return pair_times[-1]
    return rates, pair_pass_last, pairs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=316, help="lattice side (316: 1e5 particles)")
    ap.add_argument("--threads", type=int, nargs="+", default=None,
                    help="thread counts to run (default: numba's)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=10, help="evaluations timed in a round")
    ap.add_argument("--naive", type=Path, default=NAIVE, help="the naive yardstick's file")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()

    fields, h = lattice(args.side)
    columns = tuple(fields[k] for k in ("x", "y", "vx", "vy", "rho", "m", "p", "sxx", "sxy",
                                        "syy", "c"))
    n = fields["x"].size
    offsets, neighbours = build_list(fields["x"], fields["y"], 2.0 * h)
    half_offsets, half_neighbours = halve(offsets, neighbours)
    pairs = int(neighbours.size)
    widest = int(np.diff(half_offsets).max())
    reference = np.zeros((SUMS, n))
    bare(*columns, h, offsets, neighbours, reference)

    naive = load_naive(args.naive) if args.naive.is_file() else None
    naive_state = {}
    if naive is not None:
        h2 = 2 * h
        ncx = int((1 + 2 * h2) / h2) + 2
        naive_out = [np.empty(n) for _ in range(SUMS)]

        def run_naive() -> None:
            order, start, cell = naive.build_cells(fields["x"], fields["y"], h2, -h2, -h2,
                                                   ncx, ncx)
            naive.rates(*columns, h, order, start, cell, ncx, ncx, *naive_out)
        naive_state["run"] = run_naive
        naive_state["out"] = naive_out
    rates, pair_pass_last, impactsph_pairs = impactsph_rates(args.side)

    def items(threads: int) -> dict:
        buffers = np.zeros((threads, SUMS, n))
        scratch = np.zeros((threads, widest, SUMS))
        no_scratch = np.zeros((threads, 0, SUMS))
        out = np.zeros((SUMS, n))
        runs = {
            "bare": (lambda: bare(*columns, h, offsets, neighbours, out), pairs, out),
            "half": (lambda: half(*columns, h, half_offsets, half_neighbours, buffers,
                                  no_scratch, out), pairs, out),
            "half_scratch": (lambda: half(*columns, h, half_offsets, half_neighbours,
                                          buffers, scratch, out), pairs, out),
            "impactsph": (rates, impactsph_pairs, None),
        }
        if naive_state:
            runs = {"naive": (naive_state["run"], pairs, None), **runs}
        return runs

    thread_counts = args.threads or [numba.get_num_threads()]
    results: dict = {"side": args.side, "particles": n, "pairs": pairs,
                     "impactsph_pairs": impactsph_pairs, "threads": {}}
    for threads in thread_counts:
        numba.set_num_threads(threads)
        runs = items(threads)
        best = {name: math.inf for name in runs}
        pair_pass = math.inf
        diffs = {}
        for name, (run, _, out) in runs.items():  # compile, and check against the bare loop
            run()
            if out is not None:
                diffs[name] = float(np.max(np.abs(out - reference).max(axis=1)
                                           / np.abs(reference).max(axis=1)))
        if naive_state:
            naive_sums = np.array(naive_state["out"])
            diffs["naive"] = float(np.max(np.abs(naive_sums - reference).max(axis=1)
                                          / np.abs(reference).max(axis=1)))
        for _ in range(args.rounds):
            for name, (run, _, _) in runs.items():
                t0 = time.perf_counter()
                for _ in range(args.repeat):
                    run()
                best[name] = min(best[name], (time.perf_counter() - t0) / args.repeat)
                if name == "impactsph":
                    pair_pass = min(pair_pass, pair_pass_last())
        rate = {name: runs[name][1] / best[name] for name in runs}
        rate["impactsph pair pass"] = impactsph_pairs / pair_pass
        best["impactsph pair pass"] = pair_pass
        print(f"{threads} thread(s), {n} particles, {pairs / n:.2f} pairs a particle here, "
              f"{impactsph_pairs / n:.2f} in impactsph's lattice; best of {args.rounds} "
              f"rounds of {args.repeat}")
        print(f"{'kernel':22s} {'ms':>8s} {'pairs/s':>10s} {'/ naive':>8s} {'/ bare':>10s}"
              f"  largest relative difference from bare")
        for name in best:
            over_naive = rate[name] / rate["naive"] if "naive" in rate else math.nan
            diff = diffs.get(name)
            over_bare = rate[name] / rate["bare"]
            shown = "" if diff is None else f"{diff:.1e}"
            print(f"{name:22s} {best[name] * 1e3:8.2f} {rate[name]:10.3e} {over_naive:8.2f} "
                  f"{over_bare:10.2f}  {shown}")
        results["threads"][threads] = {"ms": {k: v * 1e3 for k, v in best.items()},
                                       "pairs_per_s": rate, "difference": diffs}
    if args.json:
        from bench_rates import machine_info  # (impactsph_rates put this folder on the path)
        results["machine"] = machine_info()
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
