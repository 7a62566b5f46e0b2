"""Arrays without reference counts inside the serial passes.

numba gives every array it receives from Python a reference count (a *meminfo*), and every
view taken of it inside compiled code (``table[material[i]]``, ``state[i]``, a row passed to a
model's return map) adds to that count and takes it off again: each an atomic instruction,
which also stops the processor from running the code around it out of order.  numba's
pruning removes the pairs it can match (in one block, around one branch), not those whose
increment and decrement lie in different branches of a particle's loop body.
Its threaded loops never pay for them: a ``prange`` body is compiled as a function of its own
that receives the arrays without a meminfo, so their counts are tests of a null pointer.

The serial passes (:attr:`impactsph.physics.options.PassOptions.parallel` False) have no such
function, and paid: on the Taylor bar on one thread, 18% of the run's time was spent on the two
instructions of the count's increment and decrement, and the integrator's stage took 1.9-2.1x
the threaded stage's time (docs/architecture.md, "Compile time").  So
:mod:`impactsph.codegen` starts each serial pass with ``a = borrowed(a)`` for its arguments
(:func:`borrow_arguments`): the same array, without a meminfo, as numba's threaded bodies get
it.  This is safe where the caller holds the arrays for the whole call and the pass keeps no
view of them after it returns, which is what a pass is.
"""

from __future__ import annotations

import ast

from numba.core import ir_utils, types
from numba.extending import intrinsic, overload
from numba.np.arrayobj import make_array, populate_array


def borrowed(a):
    """``a`` itself; in compiled code, an array ``a`` without its reference count (the same
    data, shape, strides and Python object, no meminfo), anything else unchanged."""
    return a


@intrinsic
def _without_meminfo(typingctx, array):
    def codegen(context, builder, signature, args):
        source = make_array(signature.args[0])(context, builder, value=args[0])
        out = make_array(signature.return_type)(context, builder)
        populate_array(out, data=source.data, shape=source.shape, strides=source.strides,
                       itemsize=source.itemsize, meminfo=None, parent=source.parent)
        return out._getvalue()

    return array(array), codegen


# (not inline="always": numba's inlining of the overload into the caller's IR left the
# caller's alias analysis without the link from the result to the argument, and its
# dead-code elimination dropped writes to the array; LLVM inlines the call anyway)
@overload(borrowed)
def _borrowed(a):
    if isinstance(a, types.Array):
        return lambda a: _without_meminfo(a)
    return lambda a: a


#: the keyword of the serial passes' decorator (physics/passes.py) that marks them
MARK = "PARALLEL_OPTION"


def _marked(node: ast.FunctionDef, serial: bool) -> bool:
    """A pass to borrow for: ``parallel=PARALLEL_OPTION`` in a serial module; ``nogil=True``
    (a pass over chunks in shares: :mod:`impactsph.physics.chunked`) in any."""
    for d in node.decorator_list:
        if not isinstance(d, ast.Call):
            continue
        for k in d.keywords:
            if serial and k.arg == "parallel" and isinstance(k.value, ast.Name) \
                    and k.value.id == MARK:
                return True
            if k.arg == "nogil" and isinstance(k.value, ast.Constant) and k.value.value is True:
                return True
    return False


def borrow_arguments(text: str, serial: bool = True) -> str:
    """``text`` (a generated passes module) with ``a = borrowed(a)`` for each argument ``a``
    of every function whose decorator passes ``parallel=PARALLEL_OPTION`` (``serial``: a
    module of serial passes) or ``nogil=True``, first after its docstring."""
    tree = ast.parse(text)
    inserts = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef) or not _marked(node, serial):
            continue
        names = [a.arg for a in node.args.args]
        body = node.body
        first = body[1] if (len(body) > 1 and isinstance(body[0], ast.Expr)
                            and isinstance(body[0].value, ast.Constant)
                            and isinstance(body[0].value.value, str)) else body[0]
        indent = " " * first.col_offset
        # one assignment each: numba's alias analysis does not see through the tuple that
        # ``a, b, c, d = borrowed(a), ...`` builds, and would drop the writes to ``a``
        inserts.append((first.lineno, "".join(f"{indent}{n} = borrowed({n})\n" for n in names)))
    lines = text.splitlines(keepends=True)
    for lineno, line in sorted(inserts, reverse=True):
        lines.insert(lineno - 1, line)
    return "".join(lines)


def _aliases_its_argument(lhs: str, args: list, alias_map: dict, arg_aliases: set) -> None:
    """numba's alias analysis: the result of :func:`borrowed` is its argument (without this,
    numba's dead-code elimination takes it for a new array and drops the writes to it)."""
    source = args[0].name
    if source in arg_aliases:
        arg_aliases.add(lhs)
    else:
        alias_map.setdefault(source, set()).add(lhs)
        alias_map.setdefault(lhs, set()).add(source)


ir_utils.alias_func_extensions[("borrowed", __name__)] = _aliases_its_argument
