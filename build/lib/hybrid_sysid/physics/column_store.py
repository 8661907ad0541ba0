"""A numba intrinsic for the dataset kernel: eight values of one column of a tile written as one row vector.

The kernel steps 16 recordings side by side, so its results come out lane-major (step, recording) while the
dataset is recording-major (recording, step). numba compiles the plain transposing loop into scalar stores,
and at paper size the copy then cost more than the arithmetic (0.19 s against 0.145 s); building the vector
from eight loads and storing it at once halves it (whole kernel 0.334 s -> 0.249 s in one run of
benchmarks/kernel_anatomy.py). No effect on values.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

WIDTH = 8


@intrinsic
def store_column8(typingctx, dst, row, col, src, channel, step, lane):
    """``dst[row, col + e] = src[channel, step + e, lane]`` for e < 8, as one vector store.

    ``dst`` must be C-contiguous (its rows are written as vectors) and of ``src``'s dtype; the caller
    guarantees the indices are in range (no bounds check, no negative-index wraparound).
    """
    indices = (row, col, channel, step, lane)
    if not (isinstance(dst, types.Array) and isinstance(src, types.Array) and dst.dtype == src.dtype
            and dst.ndim == 2 and dst.layout == "C" and src.ndim == 3
            and all(isinstance(i, types.Integer) for i in indices)):
        return None

    def codegen(context, builder, sig, args):
        dst_ty, src_ty = sig.args[0], sig.args[3]
        d = context.make_array(dst_ty)(context, builder, args[0])
        s = context.make_array(src_ty)(context, builder, args[3])
        row, col, channel, step, lane = (context.cast(builder, args[i], sig.args[i], types.intp)
                                         for i in (1, 2, 4, 5, 6))
        elt = context.get_data_type(dst_ty.dtype)
        vec_ty = ir.VectorType(elt, WIDTH)
        vec = ir.Constant(vec_ty, ir.Undefined)
        for e in range(WIDTH):
            k = builder.add(step, ir.Constant(step.type, e))
            p = cgutils.get_item_pointer(context, builder, src_ty, s, [channel, k, lane], wraparound=False)
            vec = builder.insert_element(vec, builder.load(p), ir.Constant(ir.IntType(32), e))
        q = cgutils.get_item_pointer(context, builder, dst_ty, d, [row, col], wraparound=False)
        # element alignment only: rows of the dataset start wherever numpy put them
        builder.store(vec, builder.bitcast(q, vec_ty.as_pointer()), align=context.get_abi_alignment(elt))
        return context.get_dummy_value()

    return types.void(dst, row, col, src, channel, step, lane), codegen
