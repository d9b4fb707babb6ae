"""A cache hint for the compiled message core: fetch an array row before it is read.

The event loop is bound by memory latency, not arithmetic: an event's slot row was
written when the event was queued, often thousands of events earlier, and has left
the cache by the time the event is taken (measured: the first read of the slot's
type was 11 % of the loop's samples).
:func:`prefetch` asks the CPU to start loading a row (LLVM's ``llvm.prefetch``, read,
high locality, data cache) and returns at once; the loop issues it for the events it
will take next, while it handles the current one. A prefetch never faults and changes
no value: it changes when memory is read, never what is read, so results stay
bit-identical.
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.extending import intrinsic
from numba.core.typing.templates import signature

__all__ = ["prefetch"]

_I32 = ir.IntType(32)
_IP = ir.IntType(64)
#: bytes of a cache line (x86-64, the Arm cores numba targets)
LINE = 64


@intrinsic
def prefetch(typingctx: Any, arr: Any, row: Any) -> Any:
    """Start loading row ``row`` (``0 <= row < arr.shape[0]``) of the C-contiguous
    array ``arr`` into the cache: the lines of its first byte, of one line on (at most
    its last element) and of its last element, so a row of up to two lines' length is
    asked for whole wherever it starts (an element of a 1-D array: its line). Nothing
    is returned and nothing is checked (an address outside the array is harmless to a
    prefetch, but callers keep to rows)."""
    if not isinstance(arr, types.Array) or not isinstance(row, types.Integer):
        return None

    def codegen(context: Any, builder: ir.IRBuilder, sig: Any, args: Any) -> Any:
        aryty, rowty = sig.args
        ary = context.make_array(aryty)(context, builder, args[0])
        idx = context.cast(builder, args[1], rowty, types.intp)
        zero = context.get_constant(types.intp, 0)
        one = context.get_constant(types.intp, 1)
        shape = cgutils.unpack_tuple(builder, ary.shape)
        fnty = ir.FunctionType(ir.VoidType(), [ir.IntType(8).as_pointer(), _I32, _I32, _I32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        strides = cgutils.unpack_tuple(builder, ary.strides)

        def address(inds: list[Any]) -> Any:
            ptr = cgutils.get_item_pointer2(
                context, builder, data=ary.data, shape=shape, strides=strides,
                layout=aryty.layout, inds=inds, wraparound=False, boundscheck=False)
            return builder.ptrtoint(ptr, _IP)

        first = address([idx] + [zero] * (aryty.ndim - 1))
        points = [first]
        if aryty.ndim > 1:
            # a row that does not start on a cache line (a 56 B ev_int row, a 32 B
            # ev_float row at 16 B alignment, a 96 B payload row) spans two or three
            # lines: its first byte, one line on (no further than its last element) and
            # its last element
            last = address([idx] + [builder.sub(d, one) for d in shape[1:]])
            mid = builder.add(first, ir.Constant(_IP, LINE))
            points += [builder.select(builder.icmp_unsigned("<", mid, last), mid, last), last]
        for a in points:
            i8p = builder.inttoptr(a, ir.IntType(8).as_pointer())
            # read (0), high temporal locality (3), data cache (1)
            builder.call(fn, [i8p, ir.Constant(_I32, 0), ir.Constant(_I32, 3),
                              ir.Constant(_I32, 1)])
        return context.get_dummy_value()

    return signature(types.none, arr, row), codegen
