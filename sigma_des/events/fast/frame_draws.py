"""The draw rows a trigger issue needs, filled in one pass per frame.

A trigger ``k`` needs the rows of index ``k`` of every draw table of its own kind, of
the states it causes and of the compute stream (:class:`~.tables.DrawTables`). Filling
them table by table costs a Python loop per trigger; :class:`FrameDraws` keeps the draws
of a block of consecutive frames for all those tables at once (one sampler call per
table every ``rows`` frames, as :class:`~sigma_des.core.draws.DrawBlock` does) and copies
frame ``k``'s values into the tables' rows in one compiled call. When every table's cache
maps its stream's uniforms through an elementwise quantile (``DrawCache.uniforms``), the
uniforms of all the tables are drawn in one compiled call
(:func:`~sigma_des.core.counter_rng.uniform_tables`) and each table's quantile maps its
own contiguous ``(rows, width)`` part, as :meth:`~sigma_des.core.draws.DrawCache.block`
maps its uniforms: the same bits.

The rows hold what :meth:`~.tables.DrawTables.fill` writes: draws are a pure function of
their key and a block's row is the bits of :meth:`~sigma_des.core.draws.DrawCache.vector`
of its index, so a row is (re)written with the values it would hold anyway.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.counter_rng import uniform_tables
from sigma_des.core.draws import BLOCK, BLOCK_VALUES, DrawCache, Quantile
from sigma_des.events.fast.primitives import copy_rows
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
        self._tables = np.array([c for c, _, _ in fills], dtype=np.int64)
        self._widths = np.array([cache.n_subjects for _, cache, _ in fills], dtype=np.int64)
        self._sources = [(cache, kind) for _, cache, kind in fills]
        self._blockable = all(cache.blockable for cache, _ in self._sources)
        widest = int(self._widths.max(initial=1))
        self.rows = max(1, min(BLOCK, BLOCK_VALUES // max(1, widest))) if self._blockable else 1
        self._first = 0
        self._count = 0
        #: the block's values ``[table, frame - first, subject]`` (each table's head width)
        self._block = np.zeros((len(fills), self.rows, widest))
        #: every table's stream key, kind and quantile, when all are drawn in one call
        self._merged = _merged(self._sources) if self._blockable else None

    @property
    def end(self) -> int:
        """The first frame past the block of draws held."""
        return self._first + self._count

    def fill(self, index: int) -> None:
        """Make the rows of ``index`` of every table present (``index % history``)."""
        j = index - self._first
        if not 0 <= j < self._count:
            self._draw(index)
            j = 0
        copy_rows(self._values, self._tags, self._tables, self._widths, self._block, j,
                   index % self._history, index)

    def _draw(self, index: int) -> None:
        """Draw the block of ``rows`` frames from ``index`` on (one frame unless every
        cache is blockable: the others draw one index per call)."""
        block = self._block
        if self._merged is not None:
            streams, kinds, quantiles = self._merged
            rows = self.rows
            u = uniform_tables(streams, kinds, self._widths, np.int64(index), np.int64(rows))
            off = 0
            for t, quantile in enumerate(quantiles):
                w = int(self._widths[t])
                part = u[off : off + rows * w].reshape(rows, w)
                block[t, :, :w] = part if quantile is None else quantile(part)
                off += rows * w
        elif self._blockable:
            keys = np.arange(index, index + self.rows, dtype=np.int64)
            for t, (cache, kind) in enumerate(self._sources):
                block[t, :, : self._widths[t]] = cache.block(kind, keys, 0)
        else:
            for t, (cache, kind) in enumerate(self._sources):
                block[t, 0, : self._widths[t]] = cache.vector(kind, index, 0)
        self._first = index
        self._count = self.rows


def _merged(sources: Sequence[tuple[DrawCache, int]]
            ) -> tuple[NDArray[np.uint64], NDArray[np.int64], list[Quantile | None]] | None:
    """The stream keys, kinds and quantiles of ``sources`` if each cache draws
    ``quantile(uniform)`` of its stream (``DrawCache.uniforms``, no constant), else None."""
    keys, kinds, quantiles = [], [], []
    for cache, kind in sources:
        if cache.uniforms is None or cache.constant is not None:
            return None
        key, quantile = cache.uniforms
        keys.append(key)
        kinds.append(kind)
        quantiles.append(quantile)
    return np.array(keys, dtype=np.uint64), np.array(kinds, dtype=np.int64), quantiles
