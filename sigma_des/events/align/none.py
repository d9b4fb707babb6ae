"""The ``none`` method: no alignment, each node's newest received state whatever its frame.

The baseline of docs/MODEL.md, "Alignment methods": the server shows, per node, the
state of the highest frame it has received; the snapshot's reference frame is the
highest of those.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.flags import EXACT, MISSING
from sigma_des.events.align.base import OBS_WIDTH, Aligner, ServerContext, newest_rows
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

    def on_states(
        self,
        t: NDArray[np.float64],
        nodes: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
        hlc_l: NDArray[np.float64],
        hlc_c: NDArray[np.int64],
    ) -> None:
        """Keep, per node, the batch's first state of its highest frame if that beats its own."""
        win = newest_rows(nodes, frames, self._frame)
        if win.size:
            nd = nodes[win]
            self._frame[nd] = frames[win]
            self._gen[nd] = gens[win]
            self._obs[nd] = obs[win]
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
