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
"""

from __future__ import annotations

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
