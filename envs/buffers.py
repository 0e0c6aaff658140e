"""The pieces the generated fused step (envs.fused) is written with: views of the runtime's
flat buffers without numba's checked slice and reshape (`matrix`, `column`: the step checks
its buffers' sizes once), and column writes as row loops (`put_column`, `put_rows`)."""

from __future__ import annotations

from numba import types as numba_types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic, overload


def put_column(out, k, v):
    """out[:, k] = v, v one value per row or one for all (a scalar)."""
    out[:, k] = v


@overload(put_column)
def _put_column(out, k, v):
    """Row loops in place of numpy's broadcasting assignment, whose error message (shapes
    formatted as text) alone cost about 4 s of compilation per fused step."""
    if isinstance(v, numba_types.Array) and v.ndim == 1:

        def rows(out, k, v):
            for b in range(out.shape[0]):
                out[b, k] = v[b]

        return rows
    if isinstance(v, numba_types.Array):  # one value as a 0-d array

        def zero_d(out, k, v):
            for b in range(out.shape[0]):
                out[b, k] = v[()]

        return zero_d

    def scalar(out, k, v):
        for b in range(out.shape[0]):
            out[b, k] = v

    return scalar


def put_rows(out, v):
    """out[:] = v, v one value per row."""
    out[:] = v


@overload(put_rows)
def _put_rows(out, v):
    def rows(out, v):
        for b in range(out.shape[0]):
            out[b] = v[b]

    return rows


def _contiguous(array, ndim: int) -> bool:
    return isinstance(array, numba_types.Array) and array.ndim == ndim and array.layout == "C"


def _view(context, builder, source_type, source, result_type, data, shape, strides):
    """A `result_type` array of `shape` and byte `strides` at `data`, which lies in the
    array `source` (of `source_type`): a view that keeps `source`'s memory alive."""
    array = context.make_array(source_type)(context, builder, source)
    out = context.make_array(result_type)(context, builder)
    context.populate_array(
        out,
        data=data(array),
        shape=cgutils.pack_array(builder, shape),
        strides=cgutils.pack_array(builder, strides),
        itemsize=array.itemsize,
        meminfo=array.meminfo,
        parent=array.parent,
    )
    return impl_ret_borrowed(context, builder, result_type, out._getvalue())


@intrinsic
def matrix(typingctx, buffer, offset, rows, cols):
    """buffer[offset:offset + rows * cols].reshape((rows, cols)), a view, without the
    slice's and the reshape's checks: the step checks its buffers' sizes once, and each
    checked view cost its compilation about 0.03 s (a step unpacks 10-20)."""
    if not _contiguous(buffer, 1):
        return None
    result = buffer.copy(ndim=2, layout="C")

    def codegen(context, builder, signature, args):
        start, m, k = (
            context.cast(builder, v, t, numba_types.intp)
            for v, t in zip(args[1:], signature.args[1:])
        )
        item = context.get_constant(
            numba_types.intp, context.get_abi_sizeof(context.get_data_type(buffer.dtype))
        )
        return _view(
            context,
            builder,
            buffer,
            args[0],
            result,
            lambda flat: builder.gep(flat.data, [start]),
            [m, k],
            [builder.mul(k, item), item],
        )

    return result(buffer, offset, rows, cols), codegen


@intrinsic
def column(typingctx, rows, k):
    """rows[:, k], a view (layout 'A', as numba types the slice), without the index's
    checks: k is a column of the runtime's own array, written into the step's source."""
    if not _contiguous(rows, 2):
        return None
    result = rows.copy(ndim=1, layout="A")

    def codegen(context, builder, signature, args):
        table = context.make_array(rows)(context, builder, args[0])
        k = context.cast(builder, args[1], signature.args[1], numba_types.intp)
        shape = cgutils.unpack_tuple(builder, table.shape, 2)
        strides = cgutils.unpack_tuple(builder, table.strides, 2)
        return _view(
            context,
            builder,
            rows,
            args[0],
            result,
            lambda array: builder.gep(array.data, [k]),
            [shape[0]],
            [strides[0]],
        )

    return result(rows, k), codegen
