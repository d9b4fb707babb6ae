"""The alignment methods, one module each, and the registry users pick them by name from.

docs/MODEL.md, "Alignment methods". Every method is an
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
"""

from __future__ import annotations

from typing import Protocol

from sigma_des.events.align.base import Aligner, ServerContext
from sigma_des.events.align.bides import BidesAligner
from sigma_des.events.align.hlc import HLCAligner
from sigma_des.events.align.lockstep import LockstepAligner
from sigma_des.events.align.none import NoneAligner
from sigma_des.events.align.rpc import RpcAligner
from sigma_des.events.align.spec import AlignParams

__all__ = ["ALIGNERS", "AlignerClass", "make_aligner"]


class AlignerClass(Protocol):
    """What the registry holds: a class with the uniform ``build`` constructor."""

    def build(self, n: int, ctx: ServerContext, params: AlignParams) -> Aligner:
        """An aligner for ``n`` nodes, driven through ``ctx``."""
        ...


#: The methods by name.
ALIGNERS: dict[str, AlignerClass] = {
    "none": NoneAligner,
    "lockstep": LockstepAligner,
    "hlc": HLCAligner,
    "bides": BidesAligner,
    "rpc": RpcAligner,
}


def make_aligner(method: str, n: int, ctx: ServerContext, params: AlignParams) -> Aligner:
    """The aligner of ``method`` for ``n`` nodes.

    Raises:
        KeyError: unknown method (the scenario validates method names first).
    """
    return ALIGNERS[method].build(n, ctx, params)
