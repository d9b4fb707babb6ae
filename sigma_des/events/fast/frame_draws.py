"""The draw rows a trigger issue needs, filled in one pass per frame.

A trigger ``k`` needs the rows of index ``k`` of every draw table of its own kind, of
the states it causes and of the compute stream (:class:`~.tables.DrawTables`). Filling
them table by table costs a Python loop per trigger; :class:`FrameDraws` keeps the draws
of a block of consecutive frames for all those tables at once (one sampler call per
table every ``rows`` frames, as :class:`~sigma_des.core.draws.DrawBlock` does) and copies
frame ``k``'s values into the tables' rows with one array assignment per row width.

The rows hold what :meth:`~.tables.DrawTables.fill` writes: draws are a pure function of
their key and a block's row is the bits of :meth:`~sigma_des.core.draws.DrawCache.vector`
of its index, so a row is (re)written with the values it would hold anyway.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import BLOCK, BLOCK_VALUES, DrawCache
from sigma_des.events.fast.tables import DrawTables

__all__ = ["FrameDraws"]


class FrameDraws:
    """Rows of index ``k`` of the tables of ``kinds``, filled by :meth:`fill`.

    Args:
        tables: the run's draw tables (their ``values`` and ``tags`` are written in place).
        kinds: the message kinds (0: the compute stream) whose tables a frame needs.
    """

    def __init__(self, tables: DrawTables, kinds: Sequence[int]) -> None:
        fills = [f for k in kinds for f in tables.fills_of(k)]
        self._values = tables.values
        self._tags = tables.tags
        self._history = tables.tags.shape[1]
        self._all = np.array([c for c, _, _ in fills], dtype=np.intp)
        self._blockable = all(cache.blockable for _, cache, _ in fills)
        #: per row width: the tables, their (cache, sampling kind), the block's values
        by_width: dict[int, list[tuple[int, DrawCache, int]]] = {}
        for f in fills:
            by_width.setdefault(f[1].n_subjects, []).append(f)
        self._groups = [(np.array([c for c, _, _ in g], dtype=np.intp),
                         [(cache, kind) for _, cache, kind in g], w)
                        for w, g in sorted(by_width.items())]
        widest = max(by_width, default=1)
        self.rows = max(1, min(BLOCK, BLOCK_VALUES // max(1, widest))) if self._blockable else 1
        self._first = 0
        self._count = 0
        self._blocks: list[NDArray[np.float64]] = []

    def fill(self, index: int) -> None:
        """Make the rows of ``index`` of every table present (``index % history``)."""
        j = index - self._first
        if not 0 <= j < self._count:
            self._draw(index)
            j = 0
        row = index % self._history
        values = self._values
        for (cs, _, w), block in zip(self._groups, self._blocks, strict=True):
            values[cs, row, :w] = block[:, j]
        self._tags[self._all, row] = index

    def _draw(self, index: int) -> None:
        """Draw the block of ``rows`` frames from ``index`` on (one frame unless every
        cache is blockable: the others draw one index per call)."""
        if self._blockable:
            keys = np.arange(index, index + self.rows, dtype=np.int64)
            self._blocks = [np.stack([cache.block(kind, keys, 0) for cache, kind in g])
                            for _, g, _ in self._groups]
        else:
            self._blocks = [np.stack([cache.vector(kind, index, 0) for cache, kind in g])[:, None]
                            for _, g, _ in self._groups]
        self._first = index
        self._count = self.rows
