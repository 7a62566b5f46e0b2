"""Each dimension's variant of a kernel compiled from one closure has numba cache files of its
own (:mod:`impactsph.jitcache`): with one shared index, two processes compiling two
dimensions at once could leave the index naming the other dimension's code, and the next run
that loaded it crashed."""

from __future__ import annotations

import json
import os
import subprocess
import sys

SCRIPT = r"""
import json, sys
import numpy as np
from impactsph.neighbours import _build_functions
out = {}
for dim in (2, 3):
    x = np.arange(12.0 * dim).reshape(-1, dim) ** 1.5
    ref = (x - 0.25 * np.arange(dim)).astype(np.float32)
    moved = _build_functions(dim)[1]
    value = float(moved(x, ref, np.zeros(dim)))
    out[dim] = [value, sum(moved.stats.cache_hits.values()), sum(moved.stats.cache_misses.values())]
print(json.dumps(out))
"""


def _run(cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_each_dimension_has_its_own_cache_files(tmp_path):
    first = _run(str(tmp_path))
    indexes = sorted(p.name for p in tmp_path.rglob("*max_displacement*.nbi"))
    assert len(indexes) == 2, indexes
    assert any("_2d-" in name for name in indexes) and any("_3d-" in name for name in indexes)
    # the second process loads both variants from the cache, and they compute as compiled
    second = _run(str(tmp_path))
    for dim in ("2", "3"):
        assert first[dim][1:] == [0, 1]
        assert second[dim][1:] == [1, 0]
        assert second[dim][0] == first[dim][0]
    assert first["2"][0] != first["3"][0]
