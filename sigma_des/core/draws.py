"""Lazy vectorised draw cache for per-message randomness.

A message's random numbers are keyed by ``(kind, subject, index, attempt)``
(e.g. the state of node 7 for frame 120, first transmission). Drawing them one
by one through numpy costs tens of microseconds each; instead the first request
for a ``(kind, index, attempt)`` draws the values of *all* subjects at once and
caches the vector. Because draws are counter-based, evicting and redrawing gives
the same numbers: the cache changes speed, never results.

A *blockable* cache's sampler also takes a column of indices or attempts (``(m, 1)``)
against a row of subjects (``(1, n)``) and broadcasts: :meth:`DrawCache.block` then
draws ``m`` keys in one call (:class:`DrawBlock` keeps consecutive indices for the
compiled core's per-frame table fills), each row the bits of :meth:`DrawCache.vector`
of its key (the counter hash is exact; the quantiles are elementwise ufuncs).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["BLOCK", "BLOCK_VALUES", "DrawBlock", "DrawCache"]

#: Most indices a :class:`DrawBlock` draws at once.
BLOCK = 64
#: Most values (indices x subjects) a :class:`DrawBlock` draws at once (large swarms draw
#: few indices per call: the per-call overhead is small beside their vector's cost).
BLOCK_VALUES = 4096

Sampler = Callable[[NDArray[np.int64], int, int, int], NDArray[np.float64]]
#: The inverse CDF a sampler maps its stream's uniforms through (elementwise).
Quantile = Callable[[NDArray[np.float64]], NDArray[np.float64]]

_ROWS: list[Callable[..., NDArray[np.float64]]] = []
_GRID: list[Callable[..., NDArray[np.float64]]] = []


def _uniform_rows() -> Callable[..., NDArray[np.float64]]:
    """The compiled block of a stream's uniforms (numba: imported on first use)."""
    if not _ROWS:
        from sigma_des.core.counter_rng import uniform_rows

        _ROWS.append(uniform_rows)
    return _ROWS[0]


def _uniform_grid() -> Callable[..., NDArray[np.float64]]:
    """The compiled grid of a stream's uniforms (numba: imported on first use)."""
    if not _GRID:
        from sigma_des.core.counter_rng import uniform_grid

        _GRID.append(uniform_grid)
    return _GRID[0]


def _subjects(n: int) -> NDArray[np.int64]:
    """``0 .. n-1``, one array per ``n`` shared by every cache (read, never written)."""
    a = _SUBJECTS.get(n)
    if a is None:
        if len(_SUBJECTS) >= 64:
            _SUBJECTS.clear()
        a = _SUBJECTS[n] = np.arange(n, dtype=np.int64)
    return a


_SUBJECTS: dict[int, NDArray[np.int64]] = {}


class DrawCache:
    """Values of ``sampler(subjects, kind, index, attempt)`` for all subjects, cached.

    Args:
        n_subjects: subjects are ``0 .. n_subjects-1``.
        sampler: ``f(subjects, kind, index, attempt) -> array`` (same length as subjects).
        limit: number of cached vectors kept (least recently created evicted).
        constant: every value (no draws), or None.
        blockable: the sampler broadcasts array keys (:meth:`block`).
        uniforms: ``(key, quantile)`` when the sampler is ``quantile(stream.uniform(kind,
            subjects, index, attempt))`` of the stream whose key is ``key`` (``quantile``
            None: the uniforms themselves): :meth:`block` then draws the uniforms in one
            compiled call (:func:`~sigma_des.core.counter_rng.uniform_rows`, the same bits).
    """

    __slots__ = ("_subjects", "_sampler", "_cache", "_limit", "constant", "blockable",
                 "uniforms")

    def __init__(
        self, n_subjects: int, sampler: Sampler, limit: int = 512, constant: float | None = None,
        blockable: bool = False, uniforms: tuple[np.uint64, Quantile | None] | None = None,
    ) -> None:
        self._subjects = _subjects(n_subjects)
        self._sampler = sampler
        self._cache: OrderedDict[tuple[int, int, int], NDArray[np.float64]] = OrderedDict()
        self._limit = limit
        self.constant = constant
        self.blockable = blockable
        self.uniforms = uniforms

    @property
    def n_subjects(self) -> int:
        """Number of subjects (values per vector)."""
        return len(self._subjects)

    def get(self, kind: int, subject: int, index: int, attempt: int) -> float:
        """The value for one message."""
        if self.constant is not None:
            return self.constant
        key = (kind, index, attempt)
        vec = self._cache.get(key)
        if vec is None:
            # kept as a numpy array: no per-value Python objects for the GC to scan
            vec = self._sampler(self._subjects, kind, index, attempt)
            self._cache[key] = vec
            if len(self._cache) > self._limit:
                self._cache.popitem(last=False)
        return vec.item(subject)  # type: ignore[no-any-return]

    def vector(self, kind: int, index: int, attempt: int) -> NDArray[np.float64]:
        """Values for all subjects (uncached; for batched callers)."""
        if self.constant is not None:
            return np.full(len(self._subjects), self.constant)
        return self._sampler(self._subjects, kind, index, attempt)

    def block(self, kind: int, index: int | NDArray[np.int64],
              attempt: int | NDArray[np.int64] = 0) -> NDArray[np.float64]:
        """``(m, n_subjects)`` values in one sampler call (only for a blockable cache).

        One of ``index`` and ``attempt`` is a 1-d array of ``m`` keys, the other an int;
        row ``j`` is :meth:`vector` of the ``j``-th key.
        """
        idx, att = np.asarray(index, dtype=np.int64), np.asarray(attempt, dtype=np.int64)
        if idx.ndim + att.ndim != 1:
            raise ValueError("block: one of index and attempt must be a 1-d array")
        m = idx.size if idx.ndim else att.size
        if self.constant is not None:
            return np.full((m, len(self._subjects)), self.constant)
        if not self.blockable:
            raise ValueError("block: this cache's sampler takes one index at a time")
        if self.uniforms is not None:
            key, quantile = self.uniforms
            u = _uniform_rows()(key, np.int64(kind), self._subjects, idx.reshape(-1),
                                att.reshape(-1))
            return u if quantile is None else np.ascontiguousarray(quantile(u), dtype=np.float64)
        # a blockable sampler broadcasts array keys (the Sampler type says int: the
        # per-index call every sampler supports)
        out = self._sampler(self._subjects[None, :], kind,  # type: ignore[arg-type]
                            idx[:, None] if idx.ndim else int(idx),  # type: ignore[arg-type]
                            att[:, None] if att.ndim else int(att))  # type: ignore[arg-type]
        return np.ascontiguousarray(out, dtype=np.float64)

    def grid(self, kind: int, indices: NDArray[np.int64],
             attempts: NDArray[np.int64]) -> NDArray[np.float64]:
        """``(len(indices), len(attempts), n_subjects)`` values (a blockable cache): entry
        ``[r, j]`` is :meth:`vector` of ``(kind, indices[r], attempts[j])``, the keys of a
        cache with ``uniforms`` in one compiled call (else one :meth:`block` per index)."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        att = np.asarray(attempts, dtype=np.int64).reshape(-1)
        n = len(self._subjects)
        if self.constant is not None:
            return np.full((idx.size, att.size, n), self.constant)
        if self.uniforms is None:
            out = np.empty((idx.size, att.size, n))
            for r in range(idx.size):
                out[r] = self.block(kind, int(idx[r]), att)
            return out
        key, quantile = self.uniforms
        u = _uniform_grid()(key, np.int64(kind), self._subjects, idx, att)
        return u if quantile is None else np.ascontiguousarray(quantile(u), dtype=np.float64)


class DrawBlock:
    """The draws of one ``(cache, kind)`` for a block of consecutive indices, attempt 0.

    :meth:`row` of an index outside the block draws ``rows`` indices from it in one call
    (a blockable cache; else one index per call, as :meth:`DrawCache.vector`).

    Args:
        cache: the draw cache.
        kind: the kind the cache is sampled with.
        rows: indices per block (default: :data:`BLOCK`, at most :data:`BLOCK_VALUES`
            values in all, at least one index).
    """

    __slots__ = ("cache", "kind", "first", "values", "rows")

    def __init__(self, cache: DrawCache, kind: int, rows: int | None = None) -> None:
        self.cache = cache
        self.kind = kind
        subjects = max(1, cache.n_subjects)
        self.rows = rows if rows is not None else max(1, min(BLOCK, BLOCK_VALUES // subjects))
        self.first = 0
        self.values = np.zeros((0, 0))

    def row(self, index: int) -> NDArray[np.float64]:
        """The values of all subjects at ``index`` (:meth:`DrawCache.vector`'s bits)."""
        j = index - self.first
        if 0 <= j < self.values.shape[0]:
            return self.values[j]
        if not self.cache.blockable:
            return self.cache.vector(self.kind, index, 0)
        self.first = index
        self.values = self.cache.block(self.kind, np.arange(index, index + self.rows), 0)
        return self.values[0]
