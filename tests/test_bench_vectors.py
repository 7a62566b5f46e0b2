"""``benchmarks/bench_vectors.py`` times each vector width in a process of its own against a
reference timed in the same process: one process's measurement must name the width its code
was built for and give every item's time over the reference."""

from __future__ import annotations

from impactsph.vectors import cpu_name, vector_width


def test_a_process_measures_its_items_against_its_reference(benchmark_script):
    script = benchmark_script("bench_vectors")
    row = script.measure(threads=1, rounds=1, side=30, cantilever_end=2e-5,
                         items=("rates 2D", "cantilever"))
    assert row["vectors"] == vector_width() and row["cpu"] == cpu_name()
    assert row["reference seconds"] > 0.0
    assert set(row["ratios"]) == {"rates 2D", "cantilever"}
    assert all(ratio > 0.0 for ratio in row["ratios"].values())
