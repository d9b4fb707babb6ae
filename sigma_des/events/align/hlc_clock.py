"""Hybrid logical clocks and the HLC consumer's stability buffer (DESIGN §3, ``hlc``).

:class:`HLC` implements the send and receive rules of Kulkarni et al., "Logical
Physical Clocks" (OPODIS 2014); the physical part ``pt`` is the node's (drifting)
local clock reading. A new clock starts at ``l = -inf, c = 0``: with ``-inf`` the
first event takes ``l = pt`` whatever the sign of ``pt`` (a local clock with a
negative offset reads below 0 near the start of a run), where ``l = 0`` would
pin ``l`` at 0 and count up ``c`` instead.

:class:`StabilityBuffer` is the consumer: it buffers stamped items and releases,
in HLC order, those that are causally stable — stamped at or below the minimum,
over live nodes, of the newest stamp received from each. Since every node's
stamps strictly increase, nothing stamped at or below that bound can still arrive
from a live node (over an in-order transport).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["HLC", "BatchStabilityBuffer", "Stamp", "StabilityBuffer"]


@dataclass(frozen=True, order=True)
class Stamp:
    """An HLC timestamp, ordered lexicographically by ``(l, c)``.

    Attributes:
        l: logical part (the largest physical time seen), seconds.
        c: counter breaking ties within equal ``l``.
    """

    l: float  # noqa: E741 - the name used by the paper
    c: int


class HLC:
    """One node's hybrid logical clock (starts at ``l = -inf``, ``c = 0``)."""

    __slots__ = ("l", "c")

    def __init__(self) -> None:
        self.l: float = -math.inf
        self.c: int = 0

    @property
    def stamp(self) -> Stamp:
        """The current timestamp (without advancing the clock)."""
        return Stamp(self.l, self.c)

    def send(self, pt: float) -> Stamp:
        """Advance for a send or local event at physical time ``pt``.

        ``l' = l; l = max(l', pt); c = c + 1 if l == l' else 0``.
        """
        old = self.l
        self.l = max(old, pt)
        self.c = self.c + 1 if self.l == old else 0
        return Stamp(self.l, self.c)

    def receive(self, pt: float, m: Stamp) -> Stamp:
        """Advance on receiving a message stamped ``m`` at physical time ``pt``.

        ``l' = l; l = max(l', m.l, pt)``; ``c = max(c, m.c) + 1`` if
        ``l == l' == m.l``, ``c + 1`` if only ``l == l'``, ``m.c + 1`` if only
        ``l == m.l``, else 0.
        """
        old = self.l
        new = max(old, m.l, pt)
        if new == old and new == m.l:
            self.c = max(self.c, m.c) + 1
        elif new == old:
            self.c += 1
        elif new == m.l:
            self.c = m.c + 1
        else:
            self.c = 0
        self.l = new
        return Stamp(self.l, self.c)


class StabilityBuffer:
    """Buffers stamped items and releases the causally stable ones in HLC order.

    A node that is not live (crashed or evicted) no longer blocks the bound; its
    already buffered items stay and are released with everyone else's. If no node
    is live, nothing can block: the bound is the largest stamp ever received.

    Args:
        n: number of nodes (ids ``0 … n-1``), all live initially.
    """

    def __init__(self, n: int) -> None:
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        self.n = int(n)
        self._max_l = np.full(self.n, -np.inf)
        self._max_c = np.zeros(self.n, dtype=np.int64)
        self._has = np.zeros(self.n, dtype=np.bool_)
        self._live = np.ones(self.n, dtype=np.bool_)
        # newest (l, c) per node as plain tuples: the per-message path avoids numpy scalars
        self._max_key: list[tuple[float, int] | None] = [None] * self.n
        self._heap: list[tuple[float, int, int, int, Stamp, object]] = []
        self._seq = 0
        self.peak = 0

    def _check(self, node: int) -> None:
        if not 0 <= node < self.n:
            raise IndexError(f"node must be in [0, {self.n}), got {node}")

    def add(self, node: int, stamp: Stamp, item: object) -> None:
        """Record that ``node`` sent something stamped ``stamp`` and buffer ``item``."""
        if not 0 <= node < self.n:
            self._check(node)
        key = (stamp.l, stamp.c)
        cur = self._max_key[node]
        if cur is None or key > cur:
            self._max_key[node] = key
            self._max_l[node] = stamp.l
            self._max_c[node] = stamp.c
            self._has[node] = True
        heap = self._heap
        heapq.heappush(heap, (stamp.l, stamp.c, node, self._seq, stamp, item))
        self._seq += 1
        if len(heap) > self.peak:
            self.peak = len(heap)

    def set_live(self, node: int, live: bool) -> None:
        """Mark ``node`` live (it blocks the bound) or dead (it does not)."""
        self._check(node)
        self._live[node] = bool(live)

    def bound(self) -> Stamp | None:
        """Min over live nodes of the newest stamp from each (None if one sent nothing)."""
        return _bound(self._live, self._has, self._max_l, self._max_c)

    def release(self) -> list[tuple[Stamp, int, object]]:
        """Remove and return every buffered ``(stamp, node, item)`` stamped <= the bound.

        Returns:
            The released items in HLC order, ties broken by node id (then by
            arrival order).
        """
        b = self.bound()
        out: list[tuple[Stamp, int, object]] = []
        if b is None:
            return out
        key = (b.l, b.c)
        heap = self._heap
        while heap and (heap[0][0], heap[0][1]) <= key:
            entry = heapq.heappop(heap)
            out.append((entry[4], entry[2], entry[5]))
        return out

    def __len__(self) -> int:
        return len(self._heap)


class BatchStabilityBuffer:
    """:class:`StabilityBuffer` for batches of arrivals (the cohort engine's path).

    Same bound, same release set and the same release order — by ``(l, c)``, then
    node id, then arrival order — with the items held in arrays instead of a heap.

    Args:
        n: number of nodes, all live initially.
        width: columns of the buffered ``obs`` rows.
    """

    def __init__(self, n: int, width: int) -> None:
        self.n = int(n)
        self._max_l = np.full(self.n, -np.inf)
        self._max_c = np.zeros(self.n, dtype=np.int64)
        self._has = np.zeros(self.n, dtype=np.bool_)
        self._live = np.ones(self.n, dtype=np.bool_)
        self._l = np.empty(0)
        self._c = np.empty(0, dtype=np.int64)
        self._node = np.empty(0, dtype=np.int64)
        self._seq = np.empty(0, dtype=np.int64)
        self._frame = np.empty(0, dtype=np.int64)
        self._gen = np.empty(0)
        self._obs = np.empty((0, width))
        self._next = 0
        self.peak = 0

    def add_many(
        self,
        nodes: np.ndarray,
        l: np.ndarray,  # noqa: E741 - the HLC's name
        c: np.ndarray,
        frames: np.ndarray,
        gens: np.ndarray,
        obs: np.ndarray,
    ) -> None:
        """Buffer a batch (in arrival order) and update each node's newest stamp."""
        m = nodes.size
        if m == 0:
            return
        order = np.lexsort((c, l, nodes))  # per node, the lexicographically largest last
        last = np.ones(m, dtype=np.bool_)
        last[:-1] = nodes[order[:-1]] != nodes[order[1:]]
        top = order[last]
        nd = nodes[top]
        tl, tc = l[top], c[top]
        cl, cc = self._max_l[nd], self._max_c[nd]
        newer = ~self._has[nd] | (tl > cl) | ((tl == cl) & (tc > cc))
        self._max_l[nd[newer]] = tl[newer]
        self._max_c[nd[newer]] = tc[newer]
        self._has[nd] = True
        self._l = np.concatenate([self._l, l])
        self._c = np.concatenate([self._c, c])
        self._node = np.concatenate([self._node, nodes])
        self._seq = np.concatenate([self._seq, np.arange(self._next, self._next + m)])
        self._frame = np.concatenate([self._frame, frames])
        self._gen = np.concatenate([self._gen, gens])
        self._obs = np.concatenate([self._obs, obs])
        self._next += m
        self.peak = max(self.peak, len(self))

    def set_live(self, node: int, live: bool) -> None:
        """Mark ``node`` live (it blocks the bound) or dead (it does not)."""
        self._live[node] = bool(live)

    def bound(self) -> Stamp | None:
        """Min over live nodes of the newest stamp from each (None if one sent nothing)."""
        return _bound(self._live, self._has, self._max_l, self._max_c)

    def release_arrays(
        self,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Remove the causally stable items; return their (node, frame, gen, obs) in order."""
        b = self.bound()
        if b is None or self._l.size == 0:
            return (np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64), np.empty(0),
                    np.empty((0, self._obs.shape[1])))
        stable = (self._l < b.l) | ((self._l == b.l) & (self._c <= b.c))
        idx = np.flatnonzero(stable)
        idx = idx[np.lexsort((self._seq[idx], self._node[idx], self._c[idx], self._l[idx]))]
        out = (self._node[idx], self._frame[idx], self._gen[idx], self._obs[idx])
        keep = ~stable
        self._l, self._c, self._node = self._l[keep], self._c[keep], self._node[keep]
        self._seq, self._frame = self._seq[keep], self._frame[keep]
        self._gen, self._obs = self._gen[keep], self._obs[keep]
        return out

    def __len__(self) -> int:
        return int(self._l.size)


def _bound(
    live: np.ndarray, has: np.ndarray, max_l: np.ndarray, max_c: np.ndarray
) -> Stamp | None:
    if not live.any():
        if not has.any():
            return None
        ls = np.where(has, max_l, -np.inf)
        top = ls.max()
        return Stamp(float(top), int(max_c[has & (ls == top)].max()))
    if not has[live].all():
        return None
    ls = np.where(live, max_l, np.inf)
    low = ls.min()
    return Stamp(float(low), int(max_c[live & (ls == low)].min()))
