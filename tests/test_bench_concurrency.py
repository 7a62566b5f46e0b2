"""``benchmarks/bench_concurrency.py`` captures a case's stage and pair pass and times each
share by share and both at once on numba's threads: the shares it runs must give the
results of the pass run whole (so that the times are of the real work), and every time must
be there."""

from __future__ import annotations

import numpy as np


def test_the_shares_timed_are_the_whole_pass(benchmark_script):
    script = benchmark_script("bench_concurrency")
    taken = script.capture("bars", steps=5)
    assert set(taken) == {"stage", "pair pass"}
    kernel, arguments = taken["pair pass"]
    whole = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in arguments)
    kernel(0, 1, *whole)
    shares = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in arguments)
    kernel(0, 2, *shares)
    kernel(1, 2, *shares)
    for a, b in zip(whole, shares, strict=True):
        if isinstance(a, np.ndarray):
            assert np.array_equal(a, b)
    row = script.measure_kernel("pair pass", kernel, arguments, calls=2, rounds=1)
    assert all(row[k] > 0.0 for k in ("share 0 alone", "share 1 alone", "both",
                                      "both, median", "one thread", "speedup"))
