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


def test_the_device_walk_counts_each_allocation_once_and_skips_the_host(benchmark_script):
    """``device=True`` counts CUDA arrays (the simulator's, which wrap a numpy array; a GPU's,
    whose memory pointer has an owner) once per allocation, views with their base, and none
    of the host's numpy arrays; the host walk skips the device's arrays."""
    memory = benchmark_script("bench_memory")

    class FakeCUDAArray:  # the simulator's device array: a numpy array inside
        def __init__(self, ary):
            self._ary = ary

    class DeviceNDArray:  # a GPU's: a memory pointer, views pointing at their owner
        def __init__(self, pointer):
            self.gpu_data = pointer

    simulated = np.zeros((50, 4))
    owner = SimpleNamespace(size=800, owner=None)
    view = SimpleNamespace(size=80, owner=owner)
    host = np.zeros(1000)
    root = SimpleNamespace(now={"x": FakeCUDAArray(simulated), "x0": FakeCUDAArray(simulated[:5])},
                           packed=DeviceNDArray(owner), rows=[DeviceNDArray(view)], host=host)
    device = memory.arrays_of(root, "root", device=True)
    assert sorted(size for size, _ in device.values()) == [800, 1600]
    assert [size for size, _ in memory.arrays_of(root, "root").values()] == [8000]
