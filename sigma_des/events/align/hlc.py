"""The ``hlc`` method: states shown in hybrid-logical-clock order once causally stable.

docs/concepts/methods.md: every state carries its node's HLC stamp; the
server buffers them in a :class:`~sigma_des.events.align.hlc_clock.StabilityBuffer`
and, at each alignment tick, shows the newest frame per node among the states that
became stable. A node silent for ``liveness_timeout`` no longer blocks stability
until it is heard from again.
"""

from __future__ import annotations

import numpy as np

from sigma_des.core.flags import EXACT
from sigma_des.events.align.base import (
    OBS_WIDTH,
    RECORD_BYTES,
    Aligner,
    ServerContext,
    StateBatch,
    take_newest,
)
from sigma_des.events.align.hlc_clock import StabilityBuffer
from sigma_des.events.align.spec import AlignParams, HLCSpec

__all__ = ["HLCAligner"]


class HLCAligner(Aligner):
    """Hybrid logical clocks: states shown in HLC order once causally stable.

    Args:
        n: number of nodes.
        spec: the liveness timeout.
        ctx: the engine's side of the server.
    """

    name = "hlc"

    def __init__(self, n: int, spec: HLCSpec, ctx: ServerContext) -> None:
        super().__init__(n, ctx)
        self.spec = spec
        self.buffer = StabilityBuffer(n, OBS_WIDTH)
        self._heard = np.zeros(n)
        self._live = np.ones(n, dtype=np.bool_)

    @classmethod
    def build(cls, n: int, ctx: ServerContext, params: AlignParams) -> HLCAligner:
        """The registry's constructor: ``params.hlc``."""
        return cls(n, params.hlc, ctx)

    def on_states(self, batch: StateBatch) -> None:
        """Buffer the stamped states; a node heard from again is live again."""
        buf = self.buffer
        nodes = batch.nodes
        buf.add(nodes, batch.hlc_l, batch.hlc_c, batch.frames, batch.gens, batch.obs)
        # arrival times never decrease, so the newest per node is the largest
        if nodes.size == 1:  # a single state: the same update without ufunc.at / unique
            i = int(nodes[0])
            self._heard[i] = max(self._heard[i], batch.t[0])
            back = [] if self._live[i] else [i]
        else:
            np.maximum.at(self._heard, nodes, batch.t)
            back = np.unique(nodes[~self._live[nodes]]).tolist()
        for node in back:
            self._live[node] = True
            buf.set_live(node, True)

    def align(self, t: float) -> None:
        """Mark silent nodes dead, then show the newest stable frame per node."""
        timeout = self.spec.liveness_timeout
        if timeout > 0:
            dead = self._live & (self._heard < t - timeout)
            for node in np.flatnonzero(dead).tolist():
                self._live[node] = False
                self.buffer.set_live(node, False)
        self.note_memory()
        nd = take_newest(self.shown_frame, self.shown_gen, self.shown_obs, self.buffer.release())
        self.flag[nd] = EXACT
        changed = nd.size > 0
        self.new_snapshot = changed
        if changed:
            self.aligned_frame = int(self.shown_frame.max())

    def memory_bytes(self) -> int:
        """Buffered records and the shown ones, each with its 16-byte stamp."""
        return (len(self.buffer) + self.n) * (RECORD_BYTES + 16)
