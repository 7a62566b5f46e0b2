"""The packed particle record: one row of floats per particle, in the neighbour list's cell
(Morton) order, holding everything the pair loops read of a neighbour, so that each
neighbour is two or three cache lines instead of a dozen arrays.  The CPU passes and the CUDA
kernels (:mod:`impactsph.physics.passes`) read the same layout."""

from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload


def record_columns(dim: int, correction_matrix: bool = False,
                   artificial_stress: bool = False, viscosity_factor: bool = False,
                   axisymmetric: bool = False, velocity_gradient: bool = False,
                   work_velocity: bool = False, split_positions: bool = False
                   ) -> dict[str, int]:
    """Columns of the packed record: position ``x``, velocity ``v``, ``h``, ``m``,
    ``volume = m/rho``, ``rho``, ``c``, ``pc = P/rho^2``, ``body``, the symmetric
    ``A = sigma/rho^2`` (its upper triangle, row by row: :func:`symmetric_index`); with
    ``correction_matrix`` the kernel gradient correction's ``C`` (``dim x dim``, row by row),
    with ``artificial_stress`` the symmetric artificial stress ``R`` (m^5/(kg s^2), as ``A``;
    its upper triangle like ``A``'s), with ``viscosity_factor`` the particle's factor ``f`` on
    the viscosity (a scheme with a switch), with ``axisymmetric`` the hoop stress over the
    density ``hoop`` and the radius ``radius``, with ``velocity_gradient`` the velocity
    gradient ``Lv`` (``dim x dim``, row by row; a reconstructing viscosity), with
    ``work_velocity`` the velocity ``w`` that the energy terms read (the compatible energy
    update: the velocity itself, or the step's mean velocity in its work pass), with
    ``split_positions`` (records in float32) the position's low part ``xl``, ``x - x_rounded``,
    right after ``x`` (the record's ``x`` is the position rounded, so that ``x + xl`` is the
    position to about 48 bits; a model reads it through :func:`record_coordinate`); last, the
    viscous acceleration ``u`` that the pair pass writes for a correction or a switch pass.

    ``"columns"`` is the record's length: every column, unpadded.  A run whose viscosity
    scheme has neither a correction nor a switch (nothing reads ``u``) takes records of
    ``"u"`` columns instead, without it (:meth:`impactsph.physics.rates.CpuRates.record_columns`,
    :func:`impactsph.gpu.record_columns`; the passes write ``u`` only where the records have
    it).  The CPU stores the records by row (unpadded rows were as fast as rows padded to
    whole cache lines, or faster: 3D, 1e5 particles, the pair pass 47-48 ms with 19 or 20
    columns against 49 ms with 24, in one process; benchmarks/README.md, "The records
    unpadded"), the GPU by column (:data:`impactsph.gpu.RECORD_ORDER`).  ``"width"``: the
    length padded to whole cache lines, which the GPU's rows had until they became
    columns."""
    n_sym = dim * (dim + 1) // 2
    # the position's low part follows its rounded part (:func:`record_coordinate`)
    low = dim if split_positions else 0
    cols = {"x": 0, "v": dim + low, "h": 2 * dim + low, "m": 2 * dim + 1 + low,
            "volume": 2 * dim + 2 + low, "rho": 2 * dim + 3 + low, "c": 2 * dim + 4 + low,
            "pc": 2 * dim + 5 + low, "body": 2 * dim + 6 + low, "A": 2 * dim + 7 + low}
    if split_positions:
        cols["xl"] = dim
    end = cols["A"] + n_sym
    if correction_matrix:
        cols["C"] = end
        end += dim * dim
    if artificial_stress:
        cols["R"] = end
        end += n_sym
    if viscosity_factor:  # the factor, then the switch's memory
        cols["f"] = end
        end += 2
    if axisymmetric:
        cols["hoop"] = end
        cols["radius"] = end + 1
        end += 2
    if velocity_gradient:
        cols["Lv"] = end
        end += dim * dim
    if work_velocity:
        cols["w"] = end
        end += dim
    cols["u"] = end
    end += dim
    cols["columns"] = end
    cols["width"] = (end + 7) // 8 * 8
    return cols


def symmetric_index(a: int, b: int, dim: int) -> int:
    """Position of component ``(a, b)`` of a symmetric ``dim x dim`` tensor stored as its
    upper triangle, row by row."""
    a, b = min(a, b), max(a, b)
    return a * dim - a * (a - 1) // 2 + (b - a)


def record_coordinate(P, j, X, a, dim):
    """Coordinate ``a`` of the position that row ``j`` of the packed records ``P`` holds,
    ``P[j, X + a]`` (``X``: the records' first position column, ``dim`` the dimension), in
    float64.  Float32 records (``compute.record_precision = "float32"``) hold each position in
    two parts, the position rounded to float32 and the rest, right after it (``xl``,
    :func:`record_columns` with ``split_positions``); their sum in float64 is the position to
    about 48 bits, so a pair's separation loses nothing to its distance from the origin (the
    rounded part alone is off by up to 6e-8 of that distance: 3e-4 of a spacing for bodies a
    metre away).

    For the models' own neighbour loops (a correction's or a switch's), which receive the
    records' columns as numbers and the records of either precision: compiled, the choice is
    made from ``P``'s dtype when the caller is typed, so float64 records read ``P[j, X + a]``
    alone, as before (the passes' own loops use ``record_position`` and
    ``neighbour_position`` of :mod:`impactsph.physics.passes`, which read the same columns).
    Plain Python (the CUDA simulator) takes this body."""
    if P.dtype == np.float32:
        return np.float64(P[j, X + a]) + P[j, X + dim + a]
    return P[j, X + a]


def _typed_record_coordinate(P, j, X, a, dim):
    """:func:`record_coordinate` for numba: one implementation per dtype of ``P``."""
    if P.dtype == types.float32:
        def split(P, j, X, a, dim):
            return np.float64(P[j, X + a]) + P[j, X + dim + a]
        return split

    def whole(P, j, X, a, dim):
        return P[j, X + a]
    return whole


# inlined by numba on the CPU (the vectorised neighbour loops need it before LLVM's vectoriser
# runs); on the GPU a device function, since numba-cuda does not inline through an overload at
# its own level: NVVM inlines it (the 3D correction and switch kernels' PTX has no call, both
# precisions, 2026-12-05)
overload(record_coordinate, inline="always", target="cpu")(_typed_record_coordinate)
overload(record_coordinate, target="cuda")(_typed_record_coordinate)
