"""The core's state unboxed once, and the loop's entry points that take it by address.

Calling a compiled function with the state tuple unboxes every array of it (over a
hundred descriptors, several µs) at each call, and the driver calls the loop several
times per trigger. A :class:`Handle` holds the unboxed tuple in a buffer of its own,
written once per state tuple (:func:`_store`); the entry points here take the handle,
whose unboxing reads one address, and run the loop's own entry point on a reference to
the held tuple (:class:`~sigma_des.events.fast.stateref.StateRef`, what the loop's
handlers take anyway): the same machine code on the same arrays.

Safety: the held descriptors (data pointers and shapes) point into the arrays of the
tuple the handle keeps alive. A replaced array makes a new tuple, and a growth resizes
some arrays in place: the driver makes a new handle for a new tuple and after every
growth (:meth:`CompiledCore._entries`, ``ensure_space``). The loop runs without numba's
reference counting (``_nrt=False``), so the descriptors' memory-info fields, released
after :func:`_store`, are never read.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.datamodel import models
from numba.core.extending import NativeValue, intrinsic, register_model, unbox
from numba.core.typing.templates import signature

from sigma_des.events.fast import loop
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.stateref import StateRef

__all__ = ["ENTRIES", "Handle", "HandleType"]


class HandleType(types.Type):
    """numba type: a :class:`Handle` of a state tuple of type ``tup`` (its held copy's
    address)."""

    def __init__(self, tup: types.BaseTuple) -> None:
        self.tup: Any = tup
        super().__init__(name=f"StateHandle({tup})")


@register_model(HandleType)
class _HandleModel(models.PrimitiveModel):
    def __init__(self, dmm: Any, fe_type: HandleType) -> None:
        be = dmm.lookup(fe_type.tup).get_value_type()
        super().__init__(dmm, fe_type, be.as_pointer())


@unbox(HandleType)
def _unbox(typ: HandleType, obj: Any, c: Any) -> NativeValue:
    """A handle's ``addr`` as the pointer to its held tuple (an error without one)."""
    builder = c.builder
    ptr_ty = c.context.get_value_type(typ)
    out = cgutils.alloca_once_value(builder, ir.Constant(ptr_ty, None))
    err = cgutils.alloca_once_value(builder, cgutils.false_bit)
    addr = c.pyapi.object_getattr_string(obj, "addr")
    with builder.if_else(cgutils.is_null(builder, addr)) as (missing, present):
        with missing:
            builder.store(cgutils.true_bit, err)
        with present:
            value = c.pyapi.long_as_longlong(addr)
            c.pyapi.decref(addr)
            builder.store(builder.inttoptr(value, ptr_ty), out)
    return NativeValue(builder.load(out), is_error=builder.load(err))


@intrinsic
def deref(typingctx: Any, handle: Any) -> Any:
    """The held tuple of ``handle``, as a reference (the pointer itself)."""
    if not isinstance(handle, HandleType):
        return None
    return signature(StateRef(handle.tup), handle), lambda ctx, b, sig, args: args[0]


@intrinsic
def _write(typingctx: Any, state: Any, addr: Any) -> Any:
    """Store the unboxed ``state`` at address ``addr``."""
    if not isinstance(state, types.BaseTuple):
        return None

    def codegen(context: Any, builder: ir.IRBuilder, sig: Any, args: Any) -> Any:
        ptr = builder.inttoptr(args[1], context.get_value_type(sig.args[0]).as_pointer())
        builder.store(args[0], ptr)
        return context.get_dummy_value()

    return signature(types.none, state, types.int64), codegen


@intrinsic
def _sizeof(typingctx: Any, state: Any) -> Any:
    """Bytes of the unboxed ``state``."""
    if not isinstance(state, types.BaseTuple):
        return None

    def codegen(context: Any, builder: ir.IRBuilder, sig: Any, args: Any) -> Any:
        size = context.get_abi_sizeof(context.get_value_type(sig.args[0]))
        return context.get_constant(types.int64, size)

    return signature(types.int64, state), codegen


@jit
def _size(S):  # type: ignore[no-untyped-def]
    return _sizeof(S)


@jit
def _store(S, addr):  # type: ignore[no-untyped-def]
    _write(S, addr)


class Handle:
    """State tuple ``S`` unboxed once into a buffer of its own (``addr``); keeps ``S``.

    Args:
        S: the state tuple.
        size: the bytes of its unboxed type (None: asked of ``_size``).
        store: ``_store`` compiled for its type (None: the dispatcher picks it).
    """

    __slots__ = ("S", "addr", "_buf")

    def __init__(self, S: tuple[Any, ...], size: int | None = None,
                 store: Callable[[tuple[Any, ...], int], None] | None = None) -> None:
        self.S = S
        self._buf = np.zeros(int(_size(S)) if size is None else size, dtype=np.uint8)
        self.addr = int(self._buf.ctypes.data)
        (_store if store is None else store)(S, self.addr)


# ---------------------------------------------------------------- entry points by handle


@jit
def advance(H, t_stop, strict):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.advance` on the held state."""
    return loop.advance(deref(H), t_stop, strict)


@jit
def publish_trigger(H, k, t, hlc_l, hlc_c):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.publish_trigger` on the held state."""
    loop.publish_trigger(deref(H), k, t, hlc_l, hlc_c)


@jit
def publish_commands(H, tick, stamp, nodes, rows, t):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.publish_commands` on the held state."""
    loop.publish_commands(deref(H), tick, stamp, nodes, rows, t)


@jit
def start(H, i, now):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.start` on the held state."""
    loop.start(deref(H), i, now)


@jit
def roll_back(H, i, stamp, current, now):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.roll_back` on the held state."""
    loop.roll_back(deref(H), i, stamp, current, now)


@jit
def owe_steps(H, i, steps, now):  # type: ignore[no-untyped-def]
    """:func:`~sigma_des.events.fast.loop.owe_steps` on the held state."""
    loop.owe_steps(deref(H), i, steps, now)


#: the entry points by handle, by the name of the loop's entry point each runs
ENTRIES = {"advance": advance, "publish_trigger": publish_trigger,
           "publish_commands": publish_commands, "start": start, "roll_back": roll_back,
           "owe_steps": owe_steps}
