"""``benchmarks/bench_pair_anatomy.py`` edits the generated pair pass's text; these tests
check that its edits still find the pass they measure (a changed template would otherwise
leave a variant equal to the pass, or not Python), without compiling anything."""

from __future__ import annotations

import pytest

from impactsph import codegen
from impactsph.physics import passes


@pytest.mark.parametrize("dim", [2, 3])
def test_the_variants_edit_the_neighbour_loop(dim, benchmark_script):
    anatomy = benchmark_script("bench_pair_anatomy")
    text, _ = codegen.generate(passes, dim)
    start, end = anatomy._first_loop(text)
    assert "P[j, " in text[start:end]
    for name in ("contiguous", "scratch", "empty"):
        edited = anatomy.VARIANTS[name](text)
        compile(edited, name, "exec")
        if name == "empty":
            rates = edited[edited.index("def particle_rates"):]
            assert "range(first, first):\n        j = listed[k]" in rates
            continue
        loop = edited[slice(*anatomy._first_loop(edited))]
        if name == "contiguous":  # every neighbour column from the transposed copy
            assert "P[j, " not in loop and "PT[V, jj]" in loop and "PT[M, jj]" in loop
            assert "neighbour_separation_t(xi0, xi1, xi2, hi, PT, jj)" in loop
            # the copy reaches particle_rates through the pass's signature and its call
            assert "filter_skin, PT)" in edited and "listed, starts, SKIN_FILTER, PT)" in edited
            assert "chunk_size, PT)" in edited
        else:  # the columns up to A from the scratch; the optional ones still from P
            assert "Q[V, jj]" in loop and "Q[A00, jj]" in loop
            assert "P[j, X]" not in loop and "P[j, M]" not in loop
            assert "neighbour_separation_t(xi0, xi1, xi2, hi, Q, jj)" in loop
            assert "Q = np.empty(" in edited and "filter_skin, Q)" in edited
            assert "listed, starts, SKIN_FILTER, Q)" in edited
        # the separation helper: the template's, reading the copy
        helper = edited[edited.index("def neighbour_separation_t("):]
        assert "PT[X, j]" in helper and "PT[H, j]" in helper and "P[j, " not in helper
    # the skin filter's variants edit support_range (their edit asserts it found the test)
    edited = anatomy.VARIANTS["filter_no_division"](text)
    compile(edited, "filter_no_division", "exec")
    assert anatomy.FILTER not in edited and "r2 < reach * reach" in edited
    edited = anatomy.VARIANTS["empty_unfiltered"](text)
    compile(edited, "empty_unfiltered", "exec")
    support = edited[edited.index("def support_range("):edited.index("def chunk_listed(")]
    assert "        if False:" in support and "if filter_skin:" not in support


def test_padded_rows_keep_their_entries_and_end_in_the_dummy(benchmark_script):
    """``padded`` hands the pass rows of a multiple of 8 entries: each row's own entries
    first, in order, then the index of an appended record that no sum can take anything
    from (far away, no mass or volume, another body)."""
    import numpy as np

    anatomy = benchmark_script("bench_pair_anatomy")
    record = np.arange(12.0).reshape(3, 4)
    offsets = np.array([0, 3, 11, 12])
    indices = np.array([1, 2, 0, 0, 2, 1, 1, 0, 2, 0, 1, 0], dtype=np.int32)
    columns = {"X": 0, "H": 2, "RHO": 3, "BODY": 1}
    padded, new_offsets, new_indices = anatomy._padded(record, offsets, indices, columns, 1)
    assert padded.shape == (4, 4) and (padded[:3] == record).all()
    assert padded[3, 0] == 1e30 and padded[3, 1] == -1.0 and padded[3, 2] == record[0, 2]
    assert new_offsets.tolist() == [0, 8, 16, 24]
    for p in range(3):
        row = new_indices[new_offsets[p]:new_offsets[p + 1]]
        own = indices[offsets[p]:offsets[p + 1]]
        assert row[:own.shape[0]].tolist() == own.tolist()
        assert (row[own.shape[0]:] == 3).all()
    assert new_indices.dtype == indices.dtype
