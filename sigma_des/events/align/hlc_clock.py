"""Hybrid logical clocks and the HLC consumer's stability buffer.

docs/concepts/methods.md, ``hlc``.

:class:`HLC` implements the send and receive rules of Kulkarni et al., "Logical
Physical Clocks" (OPODIS 2014); the physical part ``pt`` is the node's (drifting)
local clock reading. A new clock starts at ``l = -inf, c = 0``: with ``-inf`` the
first event takes ``l = pt`` whatever the sign of ``pt`` (a local clock with a
negative offset reads below 0 near the start of a run), where ``l = 0`` would
pin ``l`` at 0 and count up ``c`` instead.

:class:`StabilityBuffer` is the consumer: it buffers stamped states and releases,
in HLC order, those that are causally stable — stamped at or below the minimum,
over live nodes, of the newest stamp received from each. Since every node's
stamps strictly increase, nothing stamped at or below that bound can still arrive
from a live node (over an in-order transport).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["HLC", "Released", "Stamp", "StabilityBuffer"]


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
    """Buffers stamped states and releases the causally stable ones in HLC order.

    A node that is not live (crashed or evicted) no longer blocks the bound; its
    already buffered states stay and are released with everyone else's. If no node
    is live, nothing can block: the bound is the largest stamp ever received.
    States arrive in batches (a single state is a batch of one) and are held in
    arrays that grow by doubling; the release order is by ``(l, c)``, then node id,
    then arrival order.

    Args:
        n: number of nodes (ids ``0 … n-1``), all live initially.
        width: columns of the buffered ``obs`` rows.

    Attributes:
        peak: most states buffered at once so far.
    """

    def __init__(self, n: int, width: int) -> None:
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        self.n = int(n)
        self.width = int(width)
        self._max_l = np.full(self.n, -np.inf)
        self._max_c = np.zeros(self.n, dtype=np.int64)
        self._has = np.zeros(self.n, dtype=np.bool_)
        self._live = np.ones(self.n, dtype=np.bool_)
        self._m = 0  # rows in use
        self._next = 0  # arrival counter (the last tie-break)
        self._rows: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64],
                          NDArray[np.int64], NDArray[np.int64], NDArray[np.float64],
                          NDArray[np.float64]] | None = None
        self._alloc(16)
        self.peak = 0

    def _alloc(self, cap: int) -> None:
        """(Re)allocate the row arrays with capacity ``cap``, keeping the rows in use."""
        m = self._m
        old = self._rows
        rows = (
            np.empty(cap),  # l
            np.empty(cap, dtype=np.int64),  # c
            np.empty(cap, dtype=np.int64),  # node
            np.empty(cap, dtype=np.int64),  # arrival sequence
            np.empty(cap, dtype=np.int64),  # frame
            np.empty(cap),  # generation time
            np.empty((cap, self.width)),  # obs
        )
        if old is not None:
            for new_a, old_a in zip(rows, old, strict=True):
                new_a[:m] = old_a[:m]
        self._rows = rows

    def add(
        self,
        nodes: NDArray[np.int64],
        l: NDArray[np.float64],  # noqa: E741 - the HLC's name
        c: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
    ) -> None:
        """Buffer a batch (in arrival order) and update each node's newest stamp."""
        m = nodes.size
        if m == 0:
            return
        if m == 1:  # a single state: the same update on scalars
            self._add_one(int(nodes[0]), float(l[0]), int(c[0]), int(frames[0]), float(gens[0]),
                          obs[0])
            return
        order = np.lexsort((c, l, nodes))  # per node, the lexicographically largest last
        last = np.ones(m, dtype=np.bool_)
        last[:-1] = nodes[order[:-1]] != nodes[order[1:]]
        top = order[last]
        nd, tl, tc = nodes[top], l[top], c[top]
        if nd.min() < 0 or nd.max() >= self.n:
            raise IndexError(f"node must be in [0, {self.n}), got {nodes.tolist()}")
        cl, cc = self._max_l[nd], self._max_c[nd]
        newer = ~self._has[nd] | (tl > cl) | ((tl == cl) & (tc > cc))
        self._max_l[nd[newer]] = tl[newer]
        self._max_c[nd[newer]] = tc[newer]
        self._has[nd] = True
        lo, hi = self._m, self._m + m
        assert self._rows is not None
        if hi > self._rows[0].size:
            self._alloc(max(2 * self._rows[0].size, hi))
        assert self._rows is not None
        rl, rc, rn, rs, rf, rg, ro = self._rows
        rl[lo:hi] = l
        rc[lo:hi] = c
        rn[lo:hi] = nodes
        rs[lo:hi] = np.arange(self._next, self._next + m)
        rf[lo:hi] = frames
        rg[lo:hi] = gens
        ro[lo:hi] = obs
        self._m = hi
        self._next += m
        self.peak = max(self.peak, hi)

    def _add_one(
        self, node: int, l: float, c: int, frame: int, gen: float,  # noqa: E741
        obs: NDArray[np.float64],
    ) -> None:
        """:meth:`add` of one row (same rule, same row layout)."""
        if not 0 <= node < self.n:
            raise IndexError(f"node must be in [0, {self.n}), got {node}")
        if not self._has[node] or l > self._max_l[node] or (
            l == self._max_l[node] and c > self._max_c[node]
        ):
            self._max_l[node] = l
            self._max_c[node] = c
        self._has[node] = True
        j = self._m
        assert self._rows is not None
        if j == self._rows[0].size:
            self._alloc(2 * j)
        assert self._rows is not None
        rl, rc, rn, rs, rf, rg, ro = self._rows
        rl[j], rc[j], rn[j], rs[j], rf[j], rg[j] = l, c, node, self._next, frame, gen
        ro[j] = obs
        self._m = j + 1
        self._next += 1
        if self._m > self.peak:
            self.peak = self._m

    def set_live(self, node: int, live: bool) -> None:
        """Mark ``node`` live (it blocks the bound) or dead (it does not)."""
        if not 0 <= node < self.n:
            raise IndexError(f"node must be in [0, {self.n}), got {node}")
        self._live[node] = bool(live)

    def bound(self) -> Stamp | None:
        """Min over live nodes of the newest stamp from each (None if one sent nothing)."""
        return _bound(self._live, self._has, self._max_l, self._max_c)

    def release(self) -> Released:
        """Remove and return every buffered state stamped <= the bound, in release order."""
        b = self.bound()
        m = self._m
        assert self._rows is not None
        rl, rc, rn, rs, rf, rg, ro = self._rows
        if b is None or m == 0:
            return Released(np.empty(0), np.empty(0, dtype=np.int64),
                            np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64),
                            np.empty(0), np.empty((0, self.width)))
        ls, cs = rl[:m], rc[:m]
        stable = (ls < b.l) | ((ls == b.l) & (cs <= b.c))
        idx = np.flatnonzero(stable)
        idx = idx[np.lexsort((rs[idx], rn[idx], cs[idx], ls[idx]))]
        out = Released(rl[idx], rc[idx], rn[idx], rf[idx], rg[idx], ro[idx])
        keep = np.flatnonzero(~stable)
        for a in self._rows:
            a[: keep.size] = a[keep]
        self._m = int(keep.size)
        return out

    def __len__(self) -> int:
        return self._m


class Released(NamedTuple):
    """States released by :meth:`StabilityBuffer.release`, row ``j`` the ``j``-th in order."""

    l: NDArray[np.float64]  # noqa: E741 - the HLC's name
    c: NDArray[np.int64]
    nodes: NDArray[np.int64]
    frames: NDArray[np.int64]
    gens: NDArray[np.float64]
    obs: NDArray[np.float64]


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
