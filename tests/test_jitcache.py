"""Each dimension's variant of a kernel compiled from one closure has numba cache files of its
own (:mod:`impactsph.jitcache`): with one shared index, two processes compiling two
dimensions at once could leave the index naming the other dimension's code, and the next run
that loaded it crashed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

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


RACE = r"""
import sys, time
lock = sys.argv[4] == "lock"
if lock:
    import impactsph  # noqa: F401  (installs the lock)
else:  # numba's own save: the lock's effect shown by its absence
    import numba  # noqa: F401
from numba.core.caching import IndexDataCacheFile

read = IndexDataCacheFile._load_index

def slow_read(self):  # widen the window between reading the index and writing it
    overloads = read(self)
    time.sleep(1.0)
    return overloads

IndexDataCacheFile._load_index = slow_read
cache = IndexDataCacheFile(sys.argv[1], "kernel", "stamp")
from pathlib import Path
(Path(sys.argv[1]) / f"ready-{sys.argv[2]}").touch()
while not (Path(sys.argv[1]) / "go").exists():  # both start saving at once
    time.sleep(0.005)
cache.save(sys.argv[2], sys.argv[3])
"""


def _race(folder, mode: str) -> dict:
    """Two processes that each save one entry of one cache at the same moment; what a third
    then loads for each key."""
    writers = [subprocess.Popen([sys.executable, "-c", RACE, str(folder), key, f"code of {key}",
                                 mode]) for key in ("int32", "int64")]
    deadline = time.monotonic() + 120
    while not all((folder / f"ready-{key}").exists() for key in ("int32", "int64")):
        assert time.monotonic() < deadline and all(w.poll() is None for w in writers)
        time.sleep(0.01)
    (folder / "go").touch()
    assert [w.wait(timeout=120) for w in writers] == [0, 0]
    from numba.core.caching import IndexDataCacheFile

    cache = IndexDataCacheFile(str(folder), "kernel", "stamp")
    return {key: cache.load(key) for key in ("int32", "int64")}


def test_concurrent_cache_writes_keep_each_entry_its_own_code(tmp_path):
    """With the lock each key loads its own code; numba's own save, in the same race, leaves
    one key without an entry or naming the other's code (numba/numba#4807)."""
    (tmp_path / "locked").mkdir()
    assert _race(tmp_path / "locked", "lock") == {"int32": "code of int32",
                                                  "int64": "code of int64"}
    (tmp_path / "plain").mkdir()
    assert _race(tmp_path / "plain", "plain") != {"int32": "code of int32",
                                                  "int64": "code of int64"}
