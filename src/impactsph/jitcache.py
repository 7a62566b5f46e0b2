"""Numba's on-disk cache for kernels compiled once per variant (a dimension) from one closure.

Numba names a function's cache files after its module, qualified name and line, so every
variant of a closure built in a factory (``_build_functions(dim)``'s ``build``) shares one
index file and numbers its data files from 1 in it.  Two processes that compile two variants
at once (the test run's two workers, or two runs started side by side on a fresh cache) each
read the index before the other wrote it, both write their code to data file 1, and the index
of one ends up naming the code of the other: the next process that loads it runs a kernel
compiled for other arrays and crashes ("NRT_adapt_ndarray_to_python: descr is NULL").
:func:`njit_variant` gives each variant a qualified name of its own, hence files of its own,
and a variant is always compiled for one signature, so concurrent writers of one file write
the same code.

A function compiled for two signatures (two callers passing int32 and int64 arrays) has the
same race between its two entries (numba/numba#4807, open).  :func:`lock_cache_writes`, which
``import impactsph`` calls, closes it for every cached function of the process: a cache
entry is written under an exclusive lock on its index (``fcntl.flock`` on ``<index>.lock``),
the index read inside the lock, and the code file written before the index that names it.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable
from typing import Any

import numba as nb


def njit_variant(variant: str, **options: Any) -> Callable[[Callable], Any]:
    """``numba.njit(cache=True, **options)`` for one ``variant`` (e.g. ``"3d"``) of a closure:
    the function's qualified name gets ``_<variant>``, so that its cache files are its own."""
    if not re.fullmatch(r"\w+", variant):
        raise ValueError(f"variant = {variant!r}: a cache variant is letters, digits and _")

    def decorate(function: Callable) -> Any:
        function.__qualname__ = f"{function.__qualname__}_{variant}"
        return nb.njit(cache=True, **options)(function)

    return decorate


def lock_cache_writes() -> bool:
    """Make numba's cache writes safe between processes (above): wrap
    ``numba.core.caching.IndexDataCacheFile.save``.  Returns whether the lock is in place:
    False where ``fcntl`` is missing (Windows) or numba's cache file class no longer has the
    private methods the wrapper calls, which leaves numba's own ``save``."""
    try:
        import fcntl

        from numba.core.caching import IndexDataCacheFile
    except ImportError:
        return False
    original = IndexDataCacheFile.save
    if getattr(original, "locked_by_impactsph", False):
        return True
    if not all(callable(getattr(IndexDataCacheFile, name, None))
               for name in ("_load_index", "_save_index", "_save_data", "_data_name")):
        return False

    def save(self, key, data):
        index = getattr(self, "_index_path", None)
        if index is None:  # another numba's layout: its own way
            return original(self, key, data)
        try:
            handle = open(f"{index}.lock", "a")  # noqa: SIM115 (closed below)
        except OSError:  # a cache folder that cannot be written: numba's own way
            return original(self, key, data)
        with handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes
            except OSError:  # a file system without locks
                return original(self, key, data)
            overloads = self._load_index()
            name = overloads.get(key)
            if name is None:
                taken = set(overloads.values())
                name = next(self._data_name(i) for i in itertools.count(1)
                            if self._data_name(i) not in taken)
                self._save_data(name, data)  # the code, then the index that names it
                overloads[key] = name
                self._save_index(overloads)
            else:
                self._save_data(name, data)

    save.locked_by_impactsph = True
    IndexDataCacheFile.save = save
    return True
