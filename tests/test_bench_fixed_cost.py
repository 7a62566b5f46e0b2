"""``benchmarks/bench_fixed_cost.py`` times the paper's Taylor bar with 3 x 9 particles: its
worker must run that small bar (27 particles, not the paper's 1,407) and report a time a
step from whole steps."""

from __future__ import annotations


def test_the_worker_times_the_small_bar(benchmark_script, monkeypatch):
    script = benchmark_script("bench_fixed_cost")
    monkeypatch.setattr(script, "WARM_UP", 2e-6)
    monkeypatch.setattr(script, "PIECE", 2e-6)
    monkeypatch.setattr(script, "PIECES", 2)
    result = script.worker(1)
    assert result["particles"] == 27
    # a step is tens of microseconds at least: its Python alone takes that
    assert 1.0 < result["us_per_step"] < 1e6
