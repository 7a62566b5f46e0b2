"""``benchmarks/same_bits.py`` hashes every state array after a fixed number of steps: the
same run gives the same hash, and a run one step longer another (the hash sees the state)."""

from __future__ import annotations


def test_the_same_run_gives_the_same_hash_and_one_step_more_another(benchmark_script):
    script = benchmark_script("same_bits")
    first = script.state_hash("bars", ["time.max_steps=20"])
    again = script.state_hash("bars", ["time.max_steps=20"])
    longer = script.state_hash("bars", ["time.max_steps=21"])
    assert first == again and first["steps"] == 20 and len(first["sha256"]) == 64
    assert longer["steps"] == 21 and longer["sha256"] != first["sha256"]
    assert set(script.CASES) >= {"taylor-plane_stress", "taylor3d", "cantilever-ssp_rk3"}
