"""The serial passes' arrays without reference counts (:mod:`impactsph.physics.borrow`).

:func:`~impactsph.physics.borrow.borrow_arguments` starts each serial pass with ``a =
borrowed(a)`` for its arguments.  What can go wrong, and is checked here on small functions
compiled as the serial passes are (numba's parallel passes on, its ``prange`` transform off):
numba's dead-code elimination taking a borrowed array for a new one and dropping the writes to
it (it did, twice, while this was built: a run's survey came back empty); the reference counts
still being there; an array handed back to Python that is not the caller's.  That the passes
give the threaded passes' bits is ``tests/test_parallel_passes.py``'s.
"""

from __future__ import annotations

import ast
import importlib.util
import re
import sys

import numba as nb
import numpy as np
import pytest

from impactsph import codegen
from impactsph.physics import passes
from impactsph.physics.borrow import MARK, borrow_arguments, borrowed
from impactsph.physics.options import PassOptions

# (the small modules' passes, like the serial passes, have no prange loop left to transform)
pytestmark = pytest.mark.filterwarnings("ignore::numba.NumbaPerformanceWarning")

#: a module written as the template's passes are: a pass over chunks whose last writes (a
#: fold after the loop, at indices known at run time) are the ones numba's dead-code
#: elimination dropped; four arrays (a tuple ``a, b, c, d = ...`` of four lost its writes
#: too); a view of a row, read in a branch (a reference count each)
SOURCE = '''
import numba as nb
from numba.core.cpu_options import ParallelOptions

from impactsph.physics.borrow import borrowed

PARALLEL_OPTION = ParallelOptions(
    {"comprehension": False, "reduction": False, "inplace_binop": False, "setitem": False,
     "numpy": False, "stencil": False, "fusion": False, "prange": False})


@nb.njit(inline="always")
def row_total(row):
    return row[0] + row[1]


@nb.njit(inline="always")
def fold(parts, codes, n):
    parts[n, 0] = 0.0
    for k in range(n):
        parts[n, 0] += parts[k, 0]
    codes[n] = -1


@nb.njit(parallel=PARALLEL_OPTION, error_model="numpy")
def chunk_pass(n, table, material, parts, codes):
    """A pass."""
    for k in nb.prange(n):
        row = table[material[k]]
        if material[k] >= 0:
            parts[k, 0] = row_total(row)
        codes[k] = k
    fold(parts, codes, n)


@nb.njit(parallel=PARALLEL_OPTION, error_model="numpy")
def fill(values, out):
    for i in nb.prange(values.shape[0]):
        out[i] = 2.0 * values[i]
    return out
'''


def _module(tmp_path, name: str, text: str):
    path = tmp_path / f"{name}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _references(function) -> int:
    """Reference-count calls in ``function``'s own optimised LLVM IR (not its callees')."""
    (ir,) = function.inspect_llvm().values()
    own, count = False, 0
    for line in ir.splitlines():
        if line.startswith("define"):
            own = "chunk_pass" in line and "cpython" not in line and "cfunc" not in line
        elif own:
            count += len(re.findall(r"call void @NRT_(?:incref|decref)", line))
    return count


def _inputs():
    n = 6
    table = np.arange(8.0).reshape(4, 2)
    material = np.array([0, 1, -1, 3, 2, 1], dtype=np.int32)
    return n, table, material, np.full((n + 1, 1), 9.0), np.zeros(n + 1, np.int64)


def test_the_borrowed_pass_writes_what_the_plain_one_writes_without_reference_counts(
        tmp_path):
    plain = _module(tmp_path, "borrow_plain", SOURCE)
    borrowing = _module(tmp_path, "borrow_serial", borrow_arguments(SOURCE))
    expected = _inputs()
    plain.chunk_pass.py_func(*expected)
    for module in (plain, borrowing):
        got = _inputs()
        module.chunk_pass(*got)
        np.testing.assert_array_equal(got[3], expected[3])  # the fold's row included
        np.testing.assert_array_equal(got[4], expected[4])
    assert expected[4][-1] == -1 and expected[3][-1, 0] == expected[3][:-1, 0].sum()
    # the views of table's rows took and gave back a reference each in the plain pass
    assert _references(plain.chunk_pass) > 0
    assert _references(borrowing.chunk_pass) == 0


def test_an_array_handed_back_is_the_callers(tmp_path):
    borrowing = _module(tmp_path, "borrow_back", borrow_arguments(SOURCE))
    values, out = np.arange(5.0), np.zeros(5)
    back = borrowing.fill(values, out)
    assert back is out
    np.testing.assert_array_equal(out, 2.0 * values)


def test_borrowed_in_python_is_the_argument():
    a = np.zeros(3)
    assert borrowed(a) is a and borrowed(2.5) == 2.5
    assert nb.njit(lambda x: borrowed(x))(7) == 7  # not an array: unchanged


def _passes(text: str, keyword: str = "parallel") -> dict[str, ast.FunctionDef]:
    """The functions whose decorator passes ``parallel=PARALLEL_OPTION`` (``keyword``
    "parallel") or ``nogil=True`` ("nogil": the chunked passes)."""
    def marked(k: ast.keyword) -> bool:
        if keyword == "parallel":
            return k.arg == "parallel" and getattr(k.value, "id", None) == MARK
        return k.arg == "nogil" and getattr(k.value, "value", None) is True

    return {node.name: node for node in ast.walk(ast.parse(text))
            if isinstance(node, ast.FunctionDef) and any(
                isinstance(d, ast.Call) and any(marked(k) for k in d.keywords)
                for d in node.decorator_list)}


def _borrows_every_argument_first(node: ast.FunctionDef) -> bool:
    arguments = [a.arg for a in node.args.args]
    first = node.body[1:1 + len(arguments)]
    return [ast.unparse(s) for s in first] == [f"{a} = borrowed({a})" for a in arguments]


def test_every_serial_pass_borrows_every_argument_first():
    """In the generated serial module each pass marked ``parallel=PARALLEL_OPTION`` starts,
    after its docstring, with one ``a = borrowed(a)`` per argument, in order; the threaded
    module's ``prange`` passes have none (numba's threaded bodies get their arrays that way
    already).  The chunked passes (``nogil=True``: :mod:`impactsph.physics.chunked`) borrow
    in both modules."""
    serial, _ = codegen.generate(passes, 2, PassOptions(parallel=False))
    threaded, _ = codegen.generate(passes, 2, PassOptions(parallel=True))
    found = _passes(serial)
    assert {"particle_pass", "correction_pass"} <= set(found)
    for name, node in found.items():
        assert _borrows_every_argument_first(node), name
    assert set(_passes(threaded)) == set(found)
    for name, node in _passes(threaded).items():
        assert "= borrowed(" not in ast.unparse(node), name
    for text in (serial, threaded):
        chunked = _passes(text, "nogil")
        assert {"moment_pass", "gradient_pass", "pair_pass", "hourglass_pass",
                "switch_pass", "stage"} <= set(chunked)
        for name, node in chunked.items():
            assert _borrows_every_argument_first(node), name


def test_the_borrowed_text_is_kept_and_read_back(tmp_path, monkeypatch):
    """``codegen._borrowed`` keeps each module's rewrite in the cache directory: the text
    it reads back is a fresh ``borrow_arguments``' to the character, the serial and the
    threaded module's are two files, and the kept file is what the next load reads (a file
    written there stands in for the rewrite; one that is not UTF-8 is made again)."""
    monkeypatch.setenv("IMPACTSPH_CACHE_DIR", str(tmp_path))
    template = codegen._template_text(passes)
    for serial in (True, False):
        assert codegen._borrowed(template, serial) == borrow_arguments(template, serial)
    kept = sorted(tmp_path.rglob("borrowed_*.txt"))
    assert len(kept) == 2
    serial_file = next(p for p in kept
                       if p.read_text() == borrow_arguments(template, serial=True))
    serial_file.write_text("# the kept rewrite\n")
    assert codegen._borrowed(template, True) == "# the kept rewrite\n"
    serial_file.write_bytes(b"\xff\xfe not text")
    assert codegen._borrowed(template, True) == borrow_arguments(template, serial=True)
    assert serial_file.read_text() == borrow_arguments(template, serial=True)
