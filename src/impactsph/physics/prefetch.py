"""A hint to the CPU's caches: fetch a row of an array before a loop reaches it.

The CPU passes walk the particles in the neighbour list's order but read and write some of
their arrays by particle number (the pair pass: the stress ``S[i]`` and the rates ``dv[i]``,
``dS[i]``, ...), so at 1e5 particles each of those rows is a cache miss that the pass waits
for (benchmarks/README.md, "What the pair pass pays for the particles' own numbering").
:func:`prefetch_row` asks for such a row a few particles ahead: LLVM's ``llvm.prefetch``,
which changes no value (a hint; an address outside the array is not read and raises
nothing), so every result stays the same to the bit.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: the cache line the hint fetches (bytes; 64 on x86-64 and most ARM cores)
LINE = 64


@intrinsic
def prefetch_row(typingctx, array, row, lines, write):
    """Fetch the first ``lines`` cache lines of ``array[row]`` (``array``'s first axis,
    whatever its layout) into every cache level, for reading (``write`` False) or for
    writing (True: the line is fetched for ownership).  ``lines`` and ``write`` are
    compile-time constants (literals); nothing is returned and no value changes."""
    if (not isinstance(array, types.Array) or not isinstance(row, types.Integer)
            or not isinstance(lines, types.IntegerLiteral)
            or not isinstance(write, types.BooleanLiteral)):
        return None
    count = lines.literal_value
    rw = 1 if write.literal_value else 0

    def codegen(context, builder, signature, args):
        values, index = args[0], args[1]
        ary = context.make_array(signature.args[0])(context, builder, values)
        byte = ir.IntType(8).as_pointer()
        data = builder.bitcast(ary.data, byte)
        stride = builder.extract_value(ary.strides, 0)
        index = context.cast(builder, index, signature.args[1], types.intp)
        start = builder.gep(data, [builder.mul(index, stride)])
        i32 = ir.IntType(32)
        hint = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [byte, i32, i32, i32]),
            "llvm.prefetch.p0i8")
        for line in range(count):  # (rw, locality 3: keep in every level, data cache)
            at = builder.gep(start, [ir.Constant(ir.IntType(64), LINE * line)])
            builder.call(hint, [at, i32(rw), i32(3), i32(1)])
        return context.get_dummy_value()

    return types.none(array, row, lines, write), codegen
