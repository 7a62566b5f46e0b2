"""``benchmarks/bench_memory.py``'s walk counts each array's memory once, views with their
base, through attributes, dicts, lists and tuples (no compiling: plain objects)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np


def test_each_base_is_counted_once_through_every_container(benchmark_script):
    memory = benchmark_script("bench_memory")
    base = np.zeros((100, 3))
    other = np.zeros(100, dtype=np.int32)
    inner = SimpleNamespace(view=base[:, 0], again=base, table={"other": other})
    root = SimpleNamespace(state=inner, parts=[base[10:], (other[::2], "text")], cycle=None)
    root.cycle = root  # a cycle is walked once
    found = memory.arrays_of(root, "root")
    assert sorted(size for size, _ in found.values()) == [400, 2400]
    paths = {size: path for size, path in found.values()}
    assert paths[2400].startswith("root.") and paths[400].startswith("root.")
