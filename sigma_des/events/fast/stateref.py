"""A reference to the state tuple, so the compiled handlers take one pointer, not 72 arrays.

numba passes a tuple argument by value: every array descriptor of the state tuple
(:data:`~sigma_des.events.fast.layout.FIELDS`, ≈ 600 machine words) is pushed onto
the stack for each call LLVM does not inline, several times per message event. That
copy, not the model's arithmetic, was most of a message event's cost
(docs/concepts/decisions.md). An entry point called from Python stores the tuple once in its own
stack frame (:func:`ref`) and hands the handlers a :class:`StateRef`, a typed pointer
to it; ``S[FIELD]`` on a reference reads that one field's descriptor, so the handlers'
code is the same for a tuple and for a reference.

A reference lives only as long as the entry point's frame: handlers use it during the
call and never keep it.
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.datamodel import models
from numba.core.extending import intrinsic, lower_builtin, register_model
from numba.core.typing.templates import AbstractTemplate, infer, signature

__all__ = ["StateRef", "ref"]


class StateRef(types.Type):
    """numba type: a pointer to a state tuple of type ``tup`` held by a caller's frame."""

    def __init__(self, tup: types.BaseTuple) -> None:
        self.tup: Any = tup
        super().__init__(name=f"StateRef({tup})")


@register_model(StateRef)
class _StateRefModel(models.PrimitiveModel):
    def __init__(self, dmm: Any, fe_type: StateRef) -> None:
        be = dmm.lookup(fe_type.tup).get_value_type()
        super().__init__(dmm, fe_type, be.as_pointer())


@intrinsic
def ref(typingctx: Any, state: Any) -> Any:
    """A reference to ``state`` (stored once in this frame); a reference is returned as is."""
    if isinstance(state, StateRef):
        return signature(state, state), lambda context, builder, sig, args: args[0]
    if not isinstance(state, types.BaseTuple):
        return None
    out = StateRef(state)

    def codegen(context: Any, builder: ir.IRBuilder, sig: Any, args: Any) -> Any:
        slot = cgutils.alloca_once(builder, context.get_value_type(sig.args[0]))
        builder.store(args[0], slot)
        return slot

    return signature(out, state), codegen


@infer
class _StaticGetItemRef(AbstractTemplate):
    """``S[FIELD]`` with a constant index, typed as the tuple's own ``static_getitem``."""

    key = "static_getitem"

    def generic(self, args: Any, kws: Any) -> Any:
        state, idx = args
        if isinstance(state, StateRef) and isinstance(idx, int):
            return signature(state.tup.types[idx], *args)
        return None


@lower_builtin("static_getitem", StateRef, types.IntegerLiteral)
def _static_getitem_ref(context: Any, builder: ir.IRBuilder, sig: Any, args: Any) -> Any:
    (_ref_ty, _idx_ty), (ptr, idx) = sig.args, args
    return builder.load(cgutils.gep_inbounds(builder, ptr, 0, idx))
