"""Lazy vectorised draw cache for per-message randomness.

A message's random numbers are keyed by ``(kind, subject, index, attempt)``
(e.g. the state of node 7 for frame 120, first transmission). Drawing them one
by one through numpy costs tens of microseconds each; instead the first request
for a ``(kind, index, attempt)`` draws the values of *all* subjects at once and
caches the vector. Because draws are counter-based, evicting and redrawing gives
the same numbers: the cache changes speed, never results.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["DrawCache"]

Sampler = Callable[[NDArray[np.int64], int, int, int], NDArray[np.float64]]


class DrawCache:
    """Values of ``sampler(subjects, kind, index, attempt)`` for all subjects, cached.

    Args:
        n_subjects: subjects are ``0 .. n_subjects-1``.
        sampler: ``f(subjects, kind, index, attempt) -> array`` (same length as subjects).
        limit: number of cached vectors kept (least recently created evicted).
    """

    __slots__ = ("_subjects", "_sampler", "_cache", "_limit", "constant")

    def __init__(
        self, n_subjects: int, sampler: Sampler, limit: int = 512, constant: float | None = None
    ) -> None:
        self._subjects = np.arange(n_subjects, dtype=np.int64)
        self._sampler = sampler
        self._cache: OrderedDict[tuple[int, int, int], NDArray[np.float64]] = OrderedDict()
        self._limit = limit
        self.constant = constant

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
