"""The alignment methods, one module each, and the registry users pick them by name from.

docs/concepts/methods.md. Every method is an
:class:`~sigma_des.events.align.base.Aligner` with one batch interface
(``on_trigger``, ``on_states``, ``align``, ``report``); :data:`ALIGNERS` maps a
method's name to its class, and :func:`make_aligner` builds one from
:class:`~sigma_des.events.align.spec.AlignParams`:

* ``none`` (:mod:`.none`): each node's newest state, no alignment;
* ``lockstep`` (:mod:`.lockstep`): a central barrier per frame;
* ``hlc`` (:mod:`.hlc`, clock and stability buffer in :mod:`.hlc_clock`): HLC order
  once causally stable;
* ``bides`` (:mod:`.bides`, ring buffers and Algorithm 1 in :mod:`.ring`);
* ``rpc`` (:mod:`.rpc`): an AirSim-style synchronous RPC frame loop.

A method's module is imported when it is first built (or :data:`ALIGNERS` is read):
the specs (:mod:`.spec`) are read by the scenario without loading numba or SimPy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from sigma_des.events.align.base import Aligner, ServerContext
    from sigma_des.events.align.spec import AlignParams

__all__ = ["ALIGNERS", "AlignerClass", "aligner_class", "make_aligner"]


class AlignerClass(Protocol):
    """What the registry holds: a class with the uniform ``build`` constructor."""

    def build(self, n: int, ctx: ServerContext, params: AlignParams) -> Aligner:
        """An aligner for ``n`` nodes, driven through ``ctx``."""
        ...


#: Each method's module (under this package) and class.
_CLASSES: dict[str, tuple[str, str]] = {
    "none": ("none", "NoneAligner"),
    "lockstep": ("lockstep", "LockstepAligner"),
    "hlc": ("hlc", "HLCAligner"),
    "bides": ("bides", "BidesAligner"),
    "rpc": ("rpc", "RpcAligner"),
}


def aligner_class(method: str) -> AlignerClass:
    """The class of ``method`` (its module imported on first use).

    Raises:
        KeyError: unknown method (the scenario validates method names first).
    """
    got = _LOADED.get(method)
    if got is None:
        module, cls = _CLASSES[method]
        got = _LOADED[method] = getattr(importlib.import_module(f"{__name__}.{module}"), cls)
    return got


#: the classes imported so far, by method
_LOADED: dict[str, AlignerClass] = {}


def make_aligner(method: str, n: int, ctx: ServerContext, params: AlignParams) -> Aligner:
    """The aligner of ``method`` for ``n`` nodes.

    Raises:
        KeyError: unknown method (the scenario validates method names first).
    """
    return aligner_class(method).build(n, ctx, params)


def __getattr__(name: str) -> Any:
    if name == "ALIGNERS":  # the methods by name (imports every method's module)
        return {m: aligner_class(m) for m in _CLASSES}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
