"""``benchmarks/bench_list_build.py`` builds a case's list both ways, alternated: it must
build the one-sweep list from the last list's offsets (not fall back to two sweeps, which
would time the old build against itself) and find the two lists the same."""

from __future__ import annotations


def test_the_list_is_built_both_ways_and_compared(benchmark_script):
    script = benchmark_script("bench_list_build")
    result = script.measure("taylor", threads=1, steps=40, rounds=2)
    assert result["sweeps"] == [2, 1]
    assert result["same"] and result["entries"] > 2 * result["rows"]
    assert result["one sweep"]["min"] > 0.0 and result["two sweeps"]["min"] > 0.0
