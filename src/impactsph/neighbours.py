"""Neighbour search by a cell-linked list, cost linear in the number of particles.

Particles are binned into cubic cells whose edge is at least the search radius, so every
neighbour of a particle lies in its own cell or one of the ``3**dim - 1`` cells around it.
They are numbered cell by cell, the cells in Z (Morton) order and a cell's particles in their
given order, by a counting sort (:func:`cell_sort`).  The result is a compressed (CSR)
list: the neighbours of particle ``i`` are ``indices[offsets[i]:offsets[i + 1]]`` (``i``
itself excluded), every ``j`` with ``|x_i - x_j| < radius``.

The list is built with a *skin*: the search radius is ``2 h_max + skin``, and the list stays
valid until some particle has moved more than ``skin / 2`` from where it was when the list
was built, or the support has grown past what the radius covers
(:meth:`NeighbourList.stale`).  Pairs beyond the kernel's support are then skipped by the
pair loops, whose kernel value is zero there.

A list built with a smoothing length per particle holds, of the pairs within the radius, only
those closer than their own ``2 h_ij + skin`` (``h_ij`` the pair's mean h): where the smoothing
lengths differ (a kernel that follows the stretch, ``kernel.max_stretch``; bodies of
different widths, ``bodies.N.h_over_dx``; the solver builds it so then) the rows then do not
carry every pair out to the largest h's reach, which the pair loops would visit and skip.
The skin's argument is the same: ``h`` is fixed between two builds.

In 2D and 3D a row with a skin is held in two parts (``NeighbourList.splits``): the pairs
within their support at the build first, in the stencil's order, then the rest (the skin's),
in the reverse of it.  The 2D and 3D passes take the front part as it is and test only the
rest against the support before their vectorised loops (``passes.support_range``): a pair
that leaves the support before the next build is masked by the loop, and one that enters it
is found by the test.  (1D rows, four to six entries, are not split.)

A list may also carry an *inner list*: of each row's neighbours, those closer than a smaller
radius ``reach * 2 h_max + skin`` (the same skin), found in the same sweeps.  They are the
row's first entries, in the stencil's order, ahead of the rest of its front part (all of
them lie within the front's radius), and ``NeighbourList.inner_ends[p]`` is where they end:
the inner list costs 4 bytes a row, not 4 bytes an entry again (a copy of its own, before
2026-12-07, took 69 bytes a particle of a 3D lattice at h = 1.3 dx).  A pass whose kernel
reaches only part of the support (the acceleration correction's, ``2 h_c = h``) loops over
``indices[offsets[p]:inner_ends[p]]`` instead of the whole row: the entries it skips are the
ones that pass would have skipped by their distance, so its sums are the same to the bit
(``tests/test_neighbours.py``).  The passes that read whole rows sum the inner entries
first, then the rest of the front part, then the back part.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import cache

import numba as nb
import numpy as np

from .jitcache import njit_variant
from .kernels import SUPPORT_RADIUS
from .physics.chunked import SIMPLIFICATIONS_ONLY, numba_threads, run_chunked, threads_for

# the sweeps take numba's parallel simplifications without a loop to run in parallel (they run
# in shares, as the chunked passes do: physics/chunked.py), and numba says so at each compile
warnings.filterwarnings(
    "ignore", message=r"(?s)\s*The keyword argument 'parallel=True' was specified but no "
    r"transformation.*neighbours\.py\", line \d+:.*def sweep_rows\(")

#: relative round-off allowed when comparing ``support + skin`` with the list's radius (the
#: sum recomputed from an unchanged support may differ from the stored radius in its last bit)
RADIUS_TOLERANCE = 1e-12
#: double precision's machine epsilon (the builder's slack on the stencil cells' gaps)
EPSILON = float(np.finfo(np.float64).eps)
#: particles per work item of the builder's parallel sweeps
CHUNK = 64
#: the fewest rows a share of the list's displacement check takes (fewer: one share, no
#: threads): the check is paced by memory, and one core's share of it is less than the
#: machine's (the 2D lattice of 1e5 particles on two threads: 74-77 us in two shares against
#: 132 us in one, 2026-12-07; a share costs more than it saves below some 1e4 rows)
DISPLACEMENT_SHARE_ROWS = 16384


@nb.njit(inline="always", cache=True)
def morton_code(c0, c1, c2, dim):
    """The Morton (Z-order) code of the cell at integer coordinates ``(c0, c1, c2)`` (the first
    ``dim`` used): the coordinates' bits interleaved, ``63 // dim`` bits of each."""
    bits = 63 // dim
    z = 0
    for bit in range(bits):
        z |= ((c0 >> bit) & 1) << (bit * dim)
        if dim > 1:
            z |= ((c1 >> bit) & 1) << (bit * dim + 1)
        if dim > 2:
            z |= ((c2 >> bit) & 1) << (bit * dim + 2)
    return z


@nb.njit(cache=True)
def offsets_from(x, origin):  # pragma: no cover (compiled)
    """``(x - origin)`` in single precision, row by row (each difference in double precision,
    then rounded: numpy's ``(x - origin).astype(np.float32)`` to the bit, without its
    temporary): a list's reference positions."""
    n, dim = x.shape
    out = np.empty((n, dim), dtype=np.float32)
    for i in range(n):
        for a in range(dim):
            out[i, a] = np.float32(x[i, a] - origin[a])
    return out


@nb.njit(cache=True)
def cell_grid(x, radius):  # pragma: no cover (compiled)
    """The cells of edge ``radius`` around the rows ``x``: their lower corner ``lo`` (the
    rows' smallest coordinates; zeros without rows) and their count along each axis, at least
    one.  (Loops: numpy's ``x.min(axis=0)`` and ``max`` took 6.8 ms for 1e5 2D rows, numba's
    ``.min()`` 0.5-0.9 s to compile.)"""
    n, dim = x.shape
    lo = np.zeros(dim)
    ncell = np.ones(dim, dtype=np.int64)
    if n == 0:
        return lo, ncell
    hi = np.empty(dim)
    for a in range(dim):
        lo[a] = x[0, a]
        hi[a] = x[0, a]
    for i in range(1, n):
        for a in range(dim):
            lo[a] = min(lo[a], x[i, a])
            hi[a] = max(hi[a], x[i, a])
    for a in range(dim):
        ncell[a] = max(1, int((hi[a] - lo[a]) / radius) + 1)
    return lo, ncell


@nb.njit(cache=True)
def cell_codes(x, lo, cell, ncell):  # pragma: no cover (compiled)
    """The first half of :func:`cell_sort`: each particle's cell (its row-major number
    ``key``), each cell's count, the occupied cells and their Morton codes."""
    n, dim = x.shape
    total_cells = 1
    for a in range(dim):
        total_cells *= ncell[a]
    key = np.empty(n, dtype=np.int64)
    for i in range(n):
        k = 0
        for a in range(dim):
            k = k * ncell[a] + min(max(int((x[i, a] - lo[a]) / cell), 0), ncell[a] - 1)
        key[i] = k
    count = np.zeros(total_cells, dtype=np.int64)
    for i in range(n):
        count[key[i]] += 1
    occupied_cells = 0
    for k in range(total_cells):
        occupied_cells += 1 if count[k] > 0 else 0
    occupied = np.empty(occupied_cells, dtype=np.int64)
    m = 0
    for k in range(total_cells):
        if count[k] > 0:
            occupied[m] = k
            m += 1
    codes = np.empty(occupied_cells, dtype=np.int64)
    n1 = ncell[1] if dim > 1 else 1
    n2 = ncell[2] if dim > 2 else 1
    for m in range(occupied_cells):
        k = occupied[m]
        codes[m] = morton_code(k // (n1 * n2), (k // n2) % n1, k % n2, dim)
    return key, count, occupied, codes


@nb.njit(cache=True)
def cell_scatter(key, count, occupied, by_code):  # pragma: no cover (compiled)
    """The second half of :func:`cell_sort`: the occupied cells in the order ``by_code`` (of
    their Morton codes) given their ranges of sorted positions, and the particles scattered
    into them in their given order: ``(order, cell_start, cell_end)``."""
    cell_start = np.zeros(count.shape[0], dtype=np.int64)
    cell_end = count  # each cell's count until the end, then the cursor of the scatter
    start = 0
    for m in by_code:
        k = occupied[m]
        cell_start[k] = start
        start += cell_end[k]
        cell_end[k] = cell_start[k]
    order = np.empty(key.shape[0], dtype=np.int64)
    for i in range(key.shape[0]):
        order[cell_end[key[i]]] = i
        cell_end[key[i]] += 1
    return order, cell_start, cell_end


def cell_sort(x: np.ndarray, lo: np.ndarray, cell: float,
              ncell: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The particles sorted by cell, the cells in Z order and the particles of a cell in
    their given order (the order a stable sort by the cells' Morton codes gives), by a
    counting sort: ``(order, cell_start, cell_end)`` with ``order[p]`` the particle at sorted
    position ``p`` and the particles of the cell of row-major number ``k`` at sorted positions
    ``cell_start[k]:cell_end[k]``.  Only the occupied cells' codes are computed and sorted
    (several particles share a cell), so it costs a fraction of a sort of the particles' codes
    (the 2D build of 1e5 particles 20-23% faster than with that sort, the 3D build 6%:
    benchmarks/README.md).

    The occupied cells' codes are distinct, so numpy's sort of them (between the two
    compiled halves, :func:`cell_codes` and :func:`cell_scatter`) gives the one order any
    sort would; numba's own sort took 1.1-1.7 s of a cold first run to compile.
    """
    key, count, occupied, codes = cell_codes(x, lo, cell, ncell)
    return cell_scatter(key, count, occupied, np.argsort(codes))


def cell_order(x: np.ndarray, radius: float) -> np.ndarray:
    """The order a list of search radius ``radius`` built on the rows ``x`` (and nothing
    else) numbers them in: ``order[p]`` the row at sorted position ``p``, the cells of edge
    ``radius`` in Z order and a cell's rows in their given order (:func:`cell_sort`)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    lo, ncell = cell_grid(x, float(radius))
    return cell_sort(x, lo, float(radius), ncell)[0]


@nb.njit(inline="always", cache=True)
def kept_within2(hp, hq, support_per_h, skin, r2max, r2inner):
    """The squared distance within which a list with a radius per pair keeps the pair of
    smoothing lengths ``hp``, ``hq``: its own ``support_per_h h_ij + skin``, no further than
    the list's radius and no nearer than the inner list's (so that the inner list stays a part
    of the whole)."""
    reach = 0.5 * support_per_h * (hp + hq) + skin
    return min(r2max, max(reach * reach, r2inner))


@nb.njit(inline="always", cache=True)
def distance2(xp0, xp1, xp2, xs, q, dim):
    """``|x_p - xs[q]|^2`` for the builder's sweeps (``dim`` a compile-time constant there:
    inlined, the branches fold away)."""
    d = xp0 - xs[q, 0]
    r2 = d * d
    if dim > 1:
        d = xp1 - xs[q, 1]
        r2 += d * d
    if dim > 2:
        d = xp2 - xs[q, 2]
        r2 += d * d
    return r2


@nb.njit(inline="always", cache=True)
def running_sum(counts):
    """``counts[p + 1]`` (each row's count, ``counts[0]`` = 0) made running totals in
    place: the rows' offsets."""
    for p in range(counts.shape[0] - 1):
        counts[p + 1] += counts[p]


@nb.njit(inline="always", cache=True)
def share_first_row(share, shares, rows):
    """The first row of share ``share`` of ``shares`` of ``rows`` rows in chunks of
    :data:`CHUNK` (``sweep_rows``'s shares: a block of consecutive chunks each; ``rows`` for
    ``share = shares``)."""
    n_chunks = (rows + CHUNK - 1) // CHUNK
    return min(share * n_chunks // shares * CHUNK, rows)


#: the single sweep's room a share: this fraction more than the entries the last list held in
#: the share's rows (``NeighbourList.build``'s ``like``), and one row's largest count
ROOM = 1.1


@cache
def _build_functions(dim: int):
    """The cell-list builder for one dimension (``dim`` is a compile-time constant; the
    helpers are module functions: numba caches a closure only if it captures no compiled
    function): ``(build, max_displacement, displacement_share)``.

    ``build`` is Python that finds the cells (:func:`cell_grid`), sorts the particles by
    cell (:func:`cell_sort`), copies their positions in that order (``sorted_copies``), and
    runs ``sweep_rows`` twice (count, then store) over the rows in shares on numba's threads
    (:func:`impactsph.physics.chunked.run_chunked`), with ``running_totals`` between them;
    or, given the offsets of the list it replaces, once (count and store, each share into
    a room sized from them, ``share_rooms``), then ``compact_shares``, in 2D and 3D
    (2026-12-06: the 3D Taylor cylinder's build 0.64-0.65 of its time, the 2D Taylor bar's
    0.70-0.82; benchmarks/README.md, "The list rebuilt in one sweep").
    (One function with ``prange`` loops until 2026-12-06: numba types and compiles a
    ``prange`` loop's body twice, and the 1D builder took 11-16 s to compile on a cold cache,
    the longest compilation of the README's first command; benchmarks/README.md, "A cold
    first command: the stage and the neighbour builder in shares".)"""
    if dim not in (1, 2, 3):
        raise ValueError(f"dim = {dim!r}: the neighbour list is built for 1, 2 or 3 dimensions")

    @njit_variant(f"{dim}d")
    def sorted_copies(x, h, order):
        """The positions ``xs`` and smoothing lengths ``hs`` (none without a radius per
        pair, ``h`` empty) in the cells' order ``order``."""
        n = x.shape[0]
        per_pair = h.shape[0] > 0
        xs = np.empty((n, dim))
        hs = np.empty(n if per_pair else 0)
        for p in range(n):
            for a in range(dim):
                xs[p, a] = x[order[p], a]
            if per_pair:
                hs[p] = h[order[p]]
        return xs, hs

    @njit_variant(f"{dim}d", parallel=SIMPLIFICATIONS_ONLY, nogil=True)
    def sweep_rows(first, step, sweep, xs, hs, lo, ncell, cell_start, cell_end, radius,
                   r2max, r2inner, r2front, support_per_h, skin, h_largest, slack,
                   largest_cell, offsets, indices, inner_ends, splits, bases, used):
        """Share ``first`` of ``step`` of the rows' chunks (:data:`CHUNK` rows each) in sweep
        ``sweep``: 0 counts each row's neighbours into ``offsets[p + 1]`` (and its inner
        entries into ``inner_ends[p]``), 1 stores them, the offsets made running totals
        between the two (``running_totals``), each row's inner entries first (the row's
        inner end to ``inner_ends[p]``).  Sweep 2 does both at once: each row is stored at
        the share's next free place in ``indices``, in its region ``bases[first]:bases[first
        + 1]``, where there is room for the most a row can hold (``3**dim`` times
        ``largest_cell``, the largest cell's count), its count to ``offsets[p + 1]``, its
        front part's length to ``splits[p]`` and its inner entries' count to
        ``inner_ends[p]``; ``used[first]`` gets the entries the share stored, or -1 where
        the room ran short (the caller then sweeps twice).  ``compact_shares`` moves the
        regions together."""
        n = xs.shape[0]
        per_pair = hs.shape[0] > 0
        inner = inner_ends.shape[0] > 0
        # 2D and 3D with a skin: each row in two parts, the pairs within their support at the
        # build (or within the inner list's radius) first, in the stencil's order, then the
        # rest of the row, the skin's, stored from the row's end back (so the count sweep
        # needs no count of its own for it: the build is 5-8% slower than unsplit, 15-20%
        # with a count of its own and a branch); ``splits[p]`` is where the back part starts.
        # The 2D and 3D passes gather a row's entries within the support before their
        # vectorised loop (``passes.support_range``); they take the front part as it is, and
        # test only the back part (issue 16, benchmarks/README.md).  Without a skin the
        # radius is the support and every row is all front
        split = dim > 1
        # 3D: a stencil cell whose box lies at or beyond the radius from the particle holds
        # no neighbour of it and is skipped (its edge is the radius, so only the edge and
        # corner cells can be: on average 6.4 of the 27 cells' volume; the 3D build 6-10%
        # faster, the 2D one, where 0.9 of 9 can be, 1-4% slower with it, so it is not done
        # there).  With a radius per pair the reach is the particle's own, which prunes more
        # where most smoothing lengths are well below the largest (the stretch's lists: 3D
        # 10-15% faster, 2D 5%, so there 2D prunes too).  Each gap is taken ``slack`` short,
        # more than the round-off of the boxes' faces and of the binning, so that no cell
        # holding a neighbour is skipped: the list is the same to the bit
        prune = dim > 2 or (dim == 2 and per_pair)
        # a row with an inner list: its inner entries first (at the row's start, in the
        # stencil's order: the correction pass's sums are those of a list of their own), then
        # the rest of its front part, then its back part.  Sweep 1 knows the inner count
        # (sweep 0's) and stores each part in place; sweep 2 stores the inner entries in
        # place and the rest in a scratch row, copied in behind them at the row's end.
        # The two sweeps are the same loop: count the neighbours, then (offsets known) store
        # them; written out here, not in a helper, so that dim is a compile-time constant and the
        # small loops unroll.  The stencil's cells are visited with axis 0 fastest (the
        # order of the list); the count is branch-free (LLVM vectorises it), the store only in
        # its 3D gathering of a cell's candidates (below)
        prefilter = dim > 2
        n0 = ncell[0]
        n1 = ncell[1] if dim > 1 else 1
        n2 = ncell[2] if dim > 2 else 1
        lo0 = lo[0]
        lo1 = lo[1] if dim > 1 else 0.0
        lo2 = lo[2] if dim > 2 else 0.0
        n_chunks = (n + CHUNK - 1) // CHUNK
        # sweep 2: a row is stored at the share's next free place, as sweep 1 stores it but
        # with its back part from the most entries a row can have (``row_size``) on, then
        # moved down behind its front part
        once = dim > 1 and sweep == 2  # (1D lists are swept twice: ``build``)
        row_size = 3 ** dim * largest_cell if once else 0
        free = bases[first] if once else 0
        scratched = once and inner  # (the rest of a row in the scratch row: above)
        for chunk in range(first * n_chunks // step, (first + 1) * n_chunks // step):
            # the 3D store sweeps' scratch: a cell's candidates
            candidates = np.empty(largest_cell if prefilter and sweep > 0 else 0,
                                  dtype=np.int64)
            scratch = np.empty(row_size if scratched else 0, dtype=np.int32)
            store = scratch if scratched else indices
            for p in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n)):
                xp0 = xs[p, 0]
                xp1 = xs[p, 1] if dim > 1 else 0.0
                xp2 = xs[p, 2] if dim > 2 else 0.0
                hp = hs[p] if per_pair else 0.0
                c0 = min(max(int((xp0 - lo0) / radius), 0), n0 - 1)
                c1 = min(max(int((xp1 - lo1) / radius), 0), n1 - 1) if dim > 1 else 0
                c2 = min(max(int((xp2 - lo2) / radius), 0), n2 - 1) if dim > 2 else 0
                found = 0  # (sweep 0: the row's entries; 1 and 2: its front part's)
                found_inner = 0
                found_back = 0
                if once and free + row_size > bases[first + 1]:
                    used[first] = -1  # (the room was short: the caller sweeps twice)
                    return
                pos = free if once else offsets[p]
                back = free + row_size - 1 if once else offsets[p + 1] - 1  # the row's end
                # where the front part's entries beyond the inner ones go, and the back
                # part's end: the row's own place (sweep 1: behind the inner entries, whose
                # count sweep 0 left in inner_ends), or the scratch row's
                rest = 0 if scratched else pos + (inner_ends[p] if inner and sweep == 1
                                                  else 0)
                rest_end = row_size - 1 if scratched else back
                # pruning (3D, and 2D with a radius per pair): the particle's distances to
                # its cell's lower and upper faces on each axis (less the slack; 0 where
                # negative), the gaps to the stencil's cells, against its reach (with a
                # radius per pair its own: none of its pairs is kept further than with the
                # largest h, so a cell beyond that holds none)
                reach2 = r2max
                if per_pair:
                    reach2 = kept_within2(hp, h_largest, support_per_h, skin, r2max,
                                          r2inner)
                below0 = max(xp0 - (lo0 + c0 * radius) - slack, 0.0) if prune else 0.0
                above0 = max(lo0 + (c0 + 1) * radius - xp0 - slack, 0.0) if prune else 0.0
                below1 = max(xp1 - (lo1 + c1 * radius) - slack, 0.0) if prune else 0.0
                above1 = max(lo1 + (c1 + 1) * radius - xp1 - slack, 0.0) if prune else 0.0
                below2 = max(xp2 - (lo2 + c2 * radius) - slack, 0.0) if prune else 0.0
                above2 = max(lo2 + (c2 + 1) * radius - xp2 - slack, 0.0) if prune else 0.0
                for e2 in range(-1 if dim > 2 else 0, 2 if dim > 2 else 1):
                    k2 = c2 + e2
                    if k2 < 0 or k2 >= n2:
                        continue
                    gap2 = below2 if e2 < 0 else (above2 if e2 > 0 else 0.0)
                    gap2 = gap2 * gap2
                    for e1 in range(-1 if dim > 1 else 0, 2 if dim > 1 else 1):
                        k1 = c1 + e1
                        if k1 < 0 or k1 >= n1:
                            continue
                        gap1 = below1 if e1 < 0 else (above1 if e1 > 0 else 0.0)
                        gap12 = gap2 + gap1 * gap1
                        if prune and gap12 >= reach2:
                            continue
                        for e0 in range(-1, 2):
                            k0 = c0 + e0
                            if k0 < 0 or k0 >= n0:
                                continue
                            gap0 = below0 if e0 < 0 else (above0 if e0 > 0 else 0.0)
                            if prune and gap12 + gap0 * gap0 >= reach2:
                                continue
                            if dim == 1:
                                kc = k0
                            elif dim == 2:
                                kc = k0 * n1 + k1
                            else:
                                kc = (k0 * n1 + k1) * n2 + k2
                            q0 = cell_start[kc]
                            q1 = cell_end[kc]
                            if sweep == 0:
                                cnt = 0
                                cnt_inner = 0
                                for q in range(q0, q1):
                                    r2 = distance2(xp0, xp1, xp2, xs, q, dim)
                                    other = q != p
                                    lim = r2max
                                    if per_pair:
                                        lim = kept_within2(hp, hs[q], support_per_h, skin,
                                                           r2max, r2inner)
                                    cnt += 1 if (r2 < lim) & other else 0
                                    cnt_inner += 1 if (r2 < r2inner) & other else 0
                                found += cnt
                                found_inner += cnt_inner
                                continue
                            # 3D: the candidates within reach first, without a branch (each
                            # stored at the next free place, which advances only if it is
                            # kept: about a fifth of them are), then the store below runs
                            # over those alone (3D build 8% faster; 2D, where about half are
                            # kept, 23% slower with it)
                            u0 = q0
                            u1 = q1
                            if prefilter:
                                kept = 0
                                for q in range(q0, q1):
                                    r2 = distance2(xp0, xp1, xp2, xs, q, dim)
                                    lim = r2max
                                    if per_pair:
                                        lim = kept_within2(hp, hs[q], support_per_h, skin,
                                                           r2max, r2inner)
                                    candidates[kept] = q
                                    kept += 1 if (r2 < lim) & (q != p) else 0
                                u0 = 0
                                u1 = kept
                            for u in range(u0, u1):
                                q = candidates[u] if prefilter else u
                                if q == p:
                                    continue
                                r2 = distance2(xp0, xp1, xp2, xs, q, dim)
                                lim = r2max
                                front_lim = r2front
                                if per_pair:
                                    lim = kept_within2(hp, hs[q], support_per_h, skin,
                                                       r2max, r2inner)
                                    # (the pair's support: its reach less the
                                    # skin, as the reach was summed)
                                    rs = (0.5 * support_per_h * (hp + hs[q]) + skin) - skin
                                    front_lim = min(lim, max(rs * rs, r2inner))
                                if r2 < lim:
                                    if inner and r2 < r2inner:  # (front, the row's start)
                                        indices[pos + found_inner] = q
                                        found_inner += 1
                                        found += 1
                                        continue
                                    # the row's back part, filled from the row's end, or
                                    # its front (a select, not a branch: the two are not
                                    # predictable)
                                    to_back = split and r2 >= front_lim
                                    at = (rest_end - found_back if to_back
                                          else rest + (found - found_inner))
                                    store[at] = q
                                    found_back += 1 if to_back else 0
                                    found += 0 if to_back else 1
                if sweep == 0:
                    offsets[p + 1] = found
                    if inner:
                        inner_ends[p] = found_inner  # (a count, read by sweep 1)
                elif once:
                    if scratched:  # the rest of the front part, then the back part
                        for k in range(found - found_inner):
                            indices[free + found_inner + k] = scratch[k]
                        for k in range(found_back):
                            indices[free + found + k] = scratch[row_size - found_back + k]
                    else:
                        for k in range(found_back):  # (moved down: a copy forwards)
                            indices[free + found + k] = indices[back - found_back + 1 + k]
                    offsets[p + 1] = found + found_back
                    if inner:  # (counts, made places by compact_shares)
                        inner_ends[p] = found_inner
                    if split:
                        splits[p] = found
                    free += found + found_back
                else:
                    if split:
                        splits[p] = pos + found
                    if inner:
                        inner_ends[p] = pos + found_inner
        if once:
            used[first] = free - bases[first]

    @njit_variant(f"{dim}d")
    def running_totals(offsets):
        """The counts of sweep 0 (``offsets[p + 1]``) made running totals, and the index
        array of sweep 1, of their size."""
        n = offsets.shape[0] - 1
        running_sum(offsets)
        return np.empty(offsets[n], dtype=np.int32)

    @njit_variant(f"{dim}d")
    def compact_shares(offsets, inner_ends, splits, indices, bases, used):
        """Sweep 2's shares made the list sweeps 0 and 1 make: the counts made running
        totals, each share's region moved down to its rows' place (regions in the shares'
        order, each at or past its place: a copy forwards), each front part's length made
        its row's split and each inner count its row's inner end.  Returns the entries."""
        n = offsets.shape[0] - 1
        running_sum(offsets)
        step = used.shape[0]
        for t in range(step):
            start = share_first_row(t, step, n)
            at, source = offsets[start], bases[t]
            if at < source:  # (the first share's is in place)
                for k in range(used[t]):
                    indices[at + k] = indices[source + k]
        for p in range(splits.shape[0]):
            splits[p] += offsets[p]
        for p in range(inner_ends.shape[0]):
            inner_ends[p] += offsets[p]
        return offsets[n]

    def share_rooms(n, threads, like, row_largest):
        """The single sweep's regions: ``bases[t]`` where share ``t``'s begins, each
        :data:`ROOM` times what ``like`` (the last list's offsets) held in the share's rows,
        and ``row_largest``.  If the last list had another count of rows (ghosts come and
        go, in the cells' order among the rest), in the same fraction of its rows, times the
        ratio of the counts.  (Python on a few numbers: a share a thread.)"""
        starts = [share_first_row(t, threads, n) for t in range(threads + 1)]
        bases = np.zeros(threads + 1, dtype=np.int64)
        rows = like.shape[0] - 1
        at = 0
        for t in range(threads):
            held = int(like[starts[t + 1] * rows // n]) - int(like[starts[t] * rows // n])
            at += math.ceil(ROOM * held * n / rows) + row_largest
            bases[t + 1] = at
        return bases

    def build(x, radius, inner_radius, h, support_per_h, skin, like=None):
        """The list of the rows ``x`` within ``radius`` (with a radius per pair ``h``:
        ``support_per_h h_ij + skin``, no further), its inner list within ``inner_radius``
        (0: none; its entries each row's first, ``inner_ends`` where they end) and its rows'
        splits (2D and 3D): ``(order, offsets, indices, inner_ends, splits, sweeps, lo)``,
        ``lo`` the rows' smallest coordinates (zeros without rows).  With ``like`` (the
        offsets of the list this one replaces) in one sweep (``sweeps`` = 1) in 2D and 3D,
        unless a share's rows did not fit the room that gives them; else in two, a count and
        a store (2)."""
        n = x.shape[0]
        per_pair = h.shape[0] > 0  # a radius per pair: support_per_h h_ij + skin
        lo, ncell = cell_grid(x, radius)
        # cells in Z order (neighbouring cells mostly close in memory in 2D and 3D), the
        # particles of a cell in their given order
        order, cell_start, cell_end = cell_sort(x, lo, radius, ncell)
        xs, hs = sorted_copies(x, h, order)
        r2max = radius * radius
        r2inner = min(inner_radius, radius)
        r2inner = r2inner * r2inner  # 0: no inner list (a product, as the compiled ** 2 was)
        inner = inner_radius > 0.0
        support_now = radius - skin
        r2front = max(min(support_now * support_now, r2max), r2inner)
        h_largest = float(hs.max()) if per_pair and n > 0 else 0.0
        reach = 0.0
        for a in range(dim):
            reach = max(reach, abs(float(lo[a])) + (int(ncell[a]) + 1) * radius)
        slack = 64.0 * EPSILON * reach
        # (1D rows hold a few entries: there the count is cheap, and the single sweep's code,
        # pruned from the 1D sweep, would lengthen the README's first command's compiling)
        once = (dim > 1 and like is not None and like.shape[0] > 1 and like[-1] > 0
                and n > 0)
        largest_cell = int((cell_end - cell_start).max()) if (dim > 2 or once) and n > 0 else 0
        offsets = np.zeros(n + 1, dtype=np.int64)
        inner_ends = np.zeros(n if inner else 0, dtype=np.int64)
        splits = np.zeros(n if dim > 1 else 0, dtype=np.int64)
        threads = threads_for(n, CHUNK, True)
        arguments = (xs, hs, lo, ncell, cell_start, cell_end, radius, r2max, r2inner, r2front,
                     support_per_h, skin, h_largest, slack, largest_cell, offsets)
        if once:
            bases = share_rooms(n, threads, like, 3 ** dim * largest_cell)
            used = np.zeros(threads, dtype=np.int64)
            # (an array of its own, not numba's: its room beyond the list is given back)
            indices = np.empty(bases[-1], dtype=np.int32)
            run_chunked(sweep_rows, threads, 2, *arguments, indices, inner_ends, splits,
                        bases, used)
            if used.min() >= 0:
                entries = compact_shares(offsets, inner_ends, splits, indices, bases, used)
                indices.resize(entries, refcheck=False)
                return order, offsets, indices, inner_ends, splits, 1, lo
        indices = np.empty(0, dtype=np.int32)
        # (unread; of the single sweep's shapes, so that a build of either kind after the
        # other finds the sweep's compiled code by its arguments' kinds: chunked._address)
        bases, used = np.zeros(threads + 1, np.int64), np.zeros(threads, np.int64)
        for sweep in range(2):
            run_chunked(sweep_rows, threads, sweep, *arguments, indices, inner_ends, splits,
                        bases, used)
            if sweep == 0:
                indices = running_totals(offsets)
        return order, offsets, indices, inner_ends, splits, 2, lo

    @njit_variant(f"{dim}d")
    def max_displacement(x, x_ref, origin):
        """``max_i |x_i - origin - x_ref_i|`` (m): the list's displacement check, serial
        (``displacement_share`` the same in shares)."""
        largest = 0.0
        for i in range(x.shape[0]):
            s = 0.0
            for a in range(dim):
                d = (x[i, a] - origin[a]) - x_ref[i, a]
                s += d * d
            largest = max(largest, s)
        return math.sqrt(largest)

    @njit_variant(f"{dim}d", nogil=True)
    def displacement_share(first, step, x, x_ref, origin, largest):
        """Share ``first`` of ``step`` of ``max_displacement``'s rows (a block of consecutive
        rows each), squared, into ``largest[first]`` (:func:`run_chunked`'s shares)."""
        n = x.shape[0]
        most = 0.0
        for i in range(first * n // step, (first + 1) * n // step):
            s = 0.0
            for a in range(dim):
                d = (x[i, a] - origin[a]) - x_ref[i, a]
                s += d * d
            most = max(most, s)
        largest[first] = most

    return build, max_displacement, displacement_share


@dataclass
class NeighbourList:
    """CSR neighbour list with a Verlet skin, in *cell order*.

    The particles are numbered in the order of the cells they lie in at the build:
    ``order[p]`` is the particle at sorted position ``p``.  ``offsets`` has ``n + 1`` entries
    and ``indices[offsets[p]:offsets[p+1]]`` are the sorted positions ``q`` of the neighbours
    of ``order[p]`` within ``radius`` (so its neighbours are ``order[q]``).  The pair loops
    work on copies of the particle data in this order, so that neighbours are close in
    memory whatever order the particles were given in; the order is renewed at every
    rebuild.  ``reference_positions`` are the positions at the build (in the particles' own
    order) less ``reference_origin``, in single precision: they only need to resolve a small
    part of the skin.
    """

    offsets: np.ndarray
    indices: np.ndarray
    radius: float
    skin: float
    reference_positions: np.ndarray
    builds: int = 1
    order: np.ndarray | None = None  #: sorted position -> particle; None: the identity
    reference_origin: np.ndarray | None = None  #: subtracted from reference_positions
    #: the inner list (module docstring): the fraction of the support it covers (1: no inner
    #: list), its radius, and where each row's inner entries end: ``indices[offsets[p]:
    #: inner_ends[p]]`` are the row's pairs within the inner radius, its first entries
    inner_reach: float = 1.0
    inner_radius: float = 0.0
    inner_ends: np.ndarray | None = None
    #: 2D and 3D: where each row's back part starts (module docstring): ``indices[offsets[p]:
    #: splits[p]]`` were within their support (or the inner list's radius) at the build, the
    #: rest of the row was not.  None: no split known (1D, or a list handed in without one)
    splits: np.ndarray | None = None
    #: how many sweeps over the rows the build took: 1 (``build``'s ``like``), or 2 (a count,
    #: then a store; 0: a list handed in)
    sweeps: int = 0

    def __post_init__(self) -> None:
        if self.order is None:
            self.order = np.arange(self.offsets.shape[0] - 1, dtype=np.int32)
        if self.reference_origin is None:
            self.reference_origin = np.zeros(self.reference_positions.shape[1])
        rows = self.offsets.shape[0] - 1
        if self.inner_ends is not None and not (
                0.0 < self.inner_reach < 1.0 and self.inner_radius > self.skin
                and self.inner_ends.shape == (rows,)
                and bool(np.all(self.offsets[:-1] <= self.inner_ends))
                and bool(np.all(self.inner_ends <= self.offsets[1:]))):
            raise ValueError(f"an inner list needs its rows' ends, one per row ({rows},) "
                             f"within the row, inner_reach in (0, 1) and inner_radius above "
                             f"the skin; got "
                             f"inner_ends of shape {self.inner_ends.shape}, inner_reach = "
                             f"{self.inner_reach!r}, inner_radius = {self.inner_radius!r}")
        if self.splits is not None and self.splits.shape != (rows,):
            raise ValueError(f"splits has shape {self.splits.shape}: one entry per row of the "
                             f"list, ({rows},), or None")

    @classmethod
    def build(cls, x: np.ndarray, support: float, skin: float = 0.0,
              inner_reach: float = 1.0, h: np.ndarray | None = None,
              like: np.ndarray | None = None) -> NeighbourList:
        """All pairs closer than ``support + skin`` (``support`` = 2 h_max for eq 20), and
        with ``inner_reach`` < 1 an inner list of those closer than ``inner_reach * support +
        skin``.  With ``h`` (a smoothing length per row), only the pairs closer than their own
        ``2 h_ij + skin`` (``h_ij`` the mean; or than the inner list's radius, so that the
        inner list stays a part of the whole): every pair a pass of support ``2 h_ij`` uses,
        without the rows' entries out to the largest h's reach.

        With ``like`` (the offsets of the list this one replaces) the rows of a 2D or 3D
        list are swept once, each share of them stored in a room sized from what ``like``
        held in the same rows (:data:`ROOM`), then moved together; a share that does not fit
        makes it sweep twice, counting first, as without ``like`` (:attr:`sweeps`).  The list
        is the same either way."""
        dim = x.shape[1]
        build = _build_functions(dim)[0]
        radius = float(support + skin)
        if not 0.0 < inner_reach <= 1.0:
            raise ValueError(f"inner_reach = {inner_reach!r}: a fraction of the support in "
                             f"(0, 1]")
        inner_radius = float(inner_reach * support + skin) if inner_reach < 1.0 else 0.0
        per_pair = np.zeros(0) if h is None else np.ascontiguousarray(h, dtype=np.float64)
        if per_pair.shape[0] not in (0, x.shape[0]):
            raise ValueError(f"h has {per_pair.shape[0]} rows for {x.shape[0]} positions")
        x = np.ascontiguousarray(x)
        order, offsets, indices, inner_ends, splits, sweeps, origin = build(
            x, radius, inner_radius, per_pair, float(SUPPORT_RADIUS), float(skin), like)
        if offsets[-1] < np.iinfo(np.int32).max:  # 4 bytes per particle less
            offsets = offsets.astype(np.int32)
            inner_ends = inner_ends.astype(np.int32)
            splits = splits.astype(np.int32)
        # (the origin: the rows' smallest coordinates, which the cells' grid has found;
        # numpy's x.min(axis=0) took 50-80 us for the Taylor bar's 1,482 rows, 3.4 ms for
        # 1e5 in 2D, its inner loop two long)
        inner = inner_radius > 0.0
        return cls(offsets, indices, radius, float(skin), offsets_from(x, origin),
                   order=order.astype(np.int32), reference_origin=origin,
                   inner_reach=float(inner_reach) if inner else 1.0, inner_radius=inner_radius,
                   inner_ends=inner_ends if inner else None,
                   splits=splits if dim > 1 else None, sweeps=sweeps)

    @property
    def filter_starts(self) -> np.ndarray:
        """Where the 2D and 3D passes start testing each row's entries against the support
        (``passes.support_range``): :attr:`splits`, or, without them, each row's start (the
        whole row tested): one view of ``offsets`` while they are the same array, so that a
        pass's arguments stay the same objects from one evaluation to the next
        (:func:`impactsph.physics.chunked._address` finds them at once)."""
        if self.splits is not None:
            return self.splits
        return self._offsets_view(ends=False)

    def _offsets_view(self, ends: bool) -> np.ndarray:
        """The rows' starts ``offsets[:-1]`` or ends ``offsets[1:]`` (``ends``): one view while
        the offsets are the same array, so that a pass's arguments stay the same objects from
        one evaluation to the next (:func:`impactsph.physics.chunked._address` finds them at
        once)."""
        key = "_row_ends" if ends else "_row_starts"
        known = self.__dict__.get(key)  # (the offsets, their view)
        if known is None or known[0] is not self.offsets:
            view = self.offsets[1:] if ends else self.offsets[:-1]
            known = self.__dict__[key] = (self.offsets, view)
        return known[1]

    @property
    def rank(self) -> np.ndarray:
        """Each particle's sorted position, ``rank[order[p]] = p`` (the inverse of
        :attr:`order`), made once per build: a large run's particle pass walks the particles
        in their own order and writes each record to its row
        (``passes.own_order_particle_pass``)."""
        known = self.__dict__.get("_rank")  # (the order, its inverse)
        if known is None or known[0] is not self.order:
            rank = np.empty_like(self.order)
            rank[self.order] = np.arange(self.order.shape[0], dtype=self.order.dtype)
            known = self.__dict__["_rank"] = (self.order, rank)
        return known[1]

    def within(self, reach: float) -> np.ndarray:
        """Each row's end for a pass that needs every pair within ``reach`` times the
        support: ``indices[offsets[p]:ends[p]]`` holds them.  The inner list's
        :attr:`inner_ends` where it reaches that far, else the rows' own ends (a view of
        ``offsets``, the same object from one call to the next while the offsets are)."""
        if self.inner_ends is not None and reach <= self.inner_reach:
            return self.inner_ends
        return self._offsets_view(ends=True)

    def stale(self, x: np.ndarray, support: float) -> bool:
        """Whether the list no longer holds every pair within ``support`` of particles at
        ``x``: true once any particle has moved more than half the skin since the build
        (always, with no skin), or once ``support + skin`` exceeds the list's radius (beyond
        :data:`RADIUS_TOLERANCE`).  ``x`` may be the first rows of the positions the list was
        built from (the real particles, whose ghosts follow them)."""
        if self._moved_past_skin(x):
            return True
        # (the inner list, at ``reach * support + skin``, needs no test of its own: a support
        # that outgrows it, reach < 1, has outgrown the whole list's radius first)
        return support + self.skin > self.radius * (1 + RADIUS_TOLERANCE)

    def _moved_past_skin(self, x: np.ndarray) -> bool:
        if self.skin <= 0.0:
            return True
        _, serial, share = _build_functions(x.shape[1])
        reference = self.reference_positions  # ghosts follow their sources: x's rows only
        if reference.shape[0] != x.shape[0]:
            reference = reference[: x.shape[0]]
        n = x.shape[0]
        shares = min(numba_threads(), n // DISPLACEMENT_SHARE_ROWS) if (
            n >= 2 * DISPLACEMENT_SHARE_ROWS) else 1
        if shares <= 1:
            moved = serial(x, reference, self.reference_origin)
        else:  # in shares on numba's threads: a maximum is exact in any order
            largest = self.__dict__.get("_largest")  # (kept: the same arguments each check)
            if largest is None or largest.shape[0] != shares:
                largest = self.__dict__["_largest"] = np.empty(shares)
            run_chunked(share, shares, x, reference, self.reference_origin, largest)
            moved = math.sqrt(largest.max())
        return bool(moved > 0.5 * self.skin)

    def update(self, x: np.ndarray, support: float) -> None:
        """Rebuild in place if the list is :meth:`stale`."""
        if self.stale(x, support):
            like = self.offsets
            self.indices = None  # (freed before the new ones are made)
            new = NeighbourList.build(x, support, self.skin, self.inner_reach, like=like)
            self.offsets, self.indices, self.order = new.offsets, new.indices, new.order
            self.radius, self.reference_positions = new.radius, new.reference_positions
            self.reference_origin = new.reference_origin
            self.inner_reach, self.inner_radius = new.inner_reach, new.inner_radius
            self.inner_ends = new.inner_ends
            self.splits, self.sweeps = new.splits, new.sweeps
            self.builds += 1

    def particle_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Every stored ordered pair as particle numbers ``(rows, cols)`` (int64 arrays)."""
        rows = np.repeat(self.order, np.diff(self.offsets)).astype(np.int64)
        return rows, self.order[self.indices].astype(np.int64)

    def pairs(self) -> set[tuple[int, int]]:
        """All stored ordered pairs ``(i, j)`` of particle numbers (for tests: O(pairs))."""
        rows, cols = self.particle_pairs()
        return set(zip(rows.tolist(), cols.tolist(), strict=True))

    @property
    def n_pairs(self) -> int:
        """Number of ordered pairs (i, j) stored."""
        return int(self.indices.shape[0])


def particle_order_list(rows: np.ndarray, cols: np.ndarray, n: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The ordered pairs ``(rows, cols)`` of ``n`` particles as a list in particle order (CSR:
    the neighbours of ``i`` are ``indices[offsets[i]:offsets[i + 1]]``, increasing), so that a
    sum over them does not depend on the order in which a cell list found them."""
    sort = np.lexsort((cols, rows))
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=offsets[1:])
    return offsets, cols[sort].astype(np.int32)


def brute_force_pairs(x: np.ndarray, radius: float) -> set[tuple[int, int]]:
    """Reference O(N^2) search, for tests: ordered pairs with ``|x_i - x_j| < radius``."""
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    i, j = np.nonzero(d < radius)
    return {(int(a), int(b)) for a, b in zip(i, j, strict=True) if a != b}


@nb.njit(cache=True)
def _inner_first(offsets, indices, inner_offsets, inner_indices, moved, inner_ends):
    """:func:`inner_entries_first`'s rows, one after another: each row's entries that its
    inner row holds (a part of it in its order: one pointer walks it) first, then the rest."""
    for p in range(offsets.shape[0] - 1):
        start, end = offsets[p], offsets[p + 1]
        k, k_end = inner_offsets[p], inner_offsets[p + 1]
        at = start
        for e in range(start, end):  # the inner entries
            if k < k_end and indices[e] == inner_indices[k]:
                moved[at] = indices[e]
                at += 1
                k += 1
        if k != k_end:
            raise ValueError("an inner list's row is not a part of its row, in its order")
        inner_ends[p] = at
        k = inner_offsets[p]
        for e in range(start, end):  # the rest, in their order
            if k < k_end and indices[e] == inner_indices[k]:
                k += 1
            else:
                moved[at] = indices[e]
                at += 1


def inner_entries_first(offsets: np.ndarray, indices: np.ndarray, inner_offsets: np.ndarray,
                        inner_indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A list with an inner list of its own (``inner_indices[inner_offsets[p]:inner_offsets[p
    + 1]]``, each row's entries within the inner radius in the row's order, as lists were
    held before 2026-12-07 and checkpoints of then hold them) as it is held now: ``(indices,
    inner_ends)``, each row's inner entries moved to its start, the rest after them in their
    order (a stable partition of each row: the layout :meth:`NeighbourList.build` gives the
    same rows, the rows' splits unchanged, since inner entries lie in the front part).  One
    pass over the rows, holding the new entries alone (a restart of a large 3D run)."""
    moved = np.empty_like(indices)
    inner_ends = np.empty(offsets.shape[0] - 1, dtype=offsets.dtype)
    _inner_first(offsets, indices, inner_offsets, inner_indices, moved, inner_ends)
    return moved, inner_ends
