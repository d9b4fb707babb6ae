"""The ``none`` method: no alignment, each node's newest received state whatever its frame.

The baseline of docs/concepts/methods.md: the server shows, per node, the
state of the highest frame it has received; the snapshot's reference frame is the
highest of those.
"""

from __future__ import annotations

import numpy as np

from sigma_des.core.flags import EXACT, MISSING
from sigma_des.events.align.base import (
    OBS_WIDTH,
    Aligner,
    ServerContext,
    StateBatch,
    take_newest,
)
from sigma_des.events.align.spec import AlignParams

__all__ = ["NoneAligner"]


class NoneAligner(Aligner):
    """No alignment: each node's newest received state, whatever its frame.

    Args:
        n: number of nodes.
        ctx: the engine's side of the server.
    """

    name = "none"

    def __init__(self, n: int, ctx: ServerContext) -> None:
        super().__init__(n, ctx)
        self._frame = np.full(n, -1, dtype=np.int64)
        self._gen = np.full(n, np.nan)
        self._obs = np.full((n, OBS_WIDTH), np.nan)
        self._dirty = False

    @classmethod
    def build(cls, n: int, ctx: ServerContext, params: AlignParams) -> NoneAligner:
        """The registry's constructor (needs no parameters)."""
        return cls(n, ctx)

    def on_states(self, batch: StateBatch) -> None:
        """Keep, per node, the batch's first state of its highest frame if that beats its own."""
        if take_newest(self._frame, self._gen, self._obs, batch).size:
            self._dirty = True

    def align(self, t: float) -> None:
        """Show the newest states if any arrived since the last tick."""
        self.new_snapshot = self._dirty
        if self._dirty:
            self.shown_frame[:] = self._frame
            self.shown_gen[:] = self._gen
            self.shown_obs[:] = self._obs
            self.flag[:] = np.where(self._frame >= 0, EXACT, MISSING)
            self.aligned_frame = int(self._frame.max())
            self._dirty = False
        self.note_memory()
