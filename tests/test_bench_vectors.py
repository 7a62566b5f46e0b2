"""``benchmarks/bench_vectors.py`` times each vector width in a process of its own against a
reference timed in the same process: one process's measurement must name the width its code
was built for and give every item's time over the reference."""

from __future__ import annotations

import pytest

from impactsph.vectors import cpu_name, vector_width


@pytest.mark.parametrize("naive", [True, False], ids=["naive", "no-naive-file"])
def test_a_process_measures_its_items_against_its_reference(benchmark_script, naive,
                                                            tmp_path, monkeypatch):
    script = benchmark_script("bench_vectors")
    if not naive:  # a checkout without ../shared (CI's): the scalar chain instead
        monkeypatch.setattr(script.bench_bare_loop, "NAIVE", tmp_path / "missing.py")
    elif not script.bench_bare_loop.NAIVE.is_file():
        pytest.skip("no ../shared/bench/naive_pairs.py beside this checkout")
    row = script.measure(threads=1, rounds=1, side=30, cantilever_end=2e-5,
                         items=("rates 2D", "cantilever"))
    assert row["vectors"] == vector_width() and row["cpu"] == cpu_name()
    assert row["reference"] in ("naive yardstick", "roots and divisions")
    assert row["reference seconds"] > 0.0
    assert set(row["ratios"]) == {"rates 2D", "cantilever"}
    assert all(ratio > 0.0 for ratio in row["ratios"].values())
