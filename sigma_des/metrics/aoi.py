"""Exact Age-of-Information accounting at the consumer (docs/concepts/metrics.md).

The AoI of node ``i`` at time ``t`` is ``t − g_i(t)``, where ``g_i(t)`` is the
generation time of the state of node ``i`` the consumer shows at ``t``. Between
updates it grows with slope 1 (a sawtooth); :class:`AoITracker` integrates it
exactly, piece by piece, as updates arrive.

Definitions (metrics window ``[t_start, t_end]``, e.g. after a warm-up):

* A node contributes from ``start_i = max(t_start, first time a state of it is
  shown)`` to ``t_end``; nodes never shown by ``t_end`` do not contribute.
* ``time_average`` = total area under the AoI curves over those intervals divided
  by their total length (the node-time average; with every node shown from
  ``t_start`` on, this is the mean over nodes of each node's time average).
* ``peak_mean`` = mean, over updates at ``t >= t_start`` that replace a shown
  state, of the AoI just before the update (``t − previous gen time``);
  ``peak_count`` is their number. A node's first state is not a peak.

An update whose generation time is not newer than the one shown is ignored; a
newer one always replaces it (even if it arrives with a larger AoI than the
delay of an older one would have had).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["AoITracker"]


class AoITracker:
    """Sawtooth integration of AoI for ``n`` nodes, O(1) per node per update.

    Args:
        n: number of nodes (ids ``0 … n-1``).
        t_start: start of the metrics window, seconds.
    """

    def __init__(self, n: int, t_start: float) -> None:
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        self.n = int(n)
        self.t_start = float(t_start)
        self._gen = np.full(self.n, np.nan)  # gen time shown (NaN = none)
        self._acc = np.full(self.n, np.nan)  # area integrated up to this time
        self._start = np.full(self.n, np.nan)  # start of the node's window
        self._area = np.zeros(self.n)
        self._peak_sum = 0.0
        self._peak_count = 0
        self._last_t = -math.inf
        self._peaks = np.empty(0)  # scratch: the peaks of one update

    def update(self, t: float, nodes: ArrayLike, gen_times: ArrayLike) -> None:
        """At time ``t`` start showing, for each node listed, a state generated at ``gen_times``.

        Args:
            t: the time the states start being shown (non-decreasing across calls).
            nodes: node ids (int array; a node listed twice keeps its newest).
            gen_times: generation times, one per node (or a scalar).
        """
        if t < self._last_t:
            raise ValueError(f"AoI updates must come in time order: {t} < {self._last_t}")
        self._last_t = t
        if np.size(nodes) == 1:
            self._update_one(t, int(np.asarray(nodes).ravel()[0]), gen_times)
            return
        nd = np.atleast_1d(np.asarray(nodes, dtype=np.int64))
        g = np.broadcast_to(np.asarray(gen_times, dtype=np.float64), nd.shape)
        if nd.size > 1 and not bool((nd[1:] > nd[:-1]).all()):  # else: unique, in order
            order = np.lexsort((g, nd))
            last = np.ones(nd.size, dtype=np.bool_)
            last[:-1] = nd[order[1:]] != nd[order[:-1]]
            keep = order[last]
            nd, g = nd[keep], g[keep]
        self._apply(t, np.ascontiguousarray(nd), np.ascontiguousarray(g, dtype=np.float64))

    def _apply(self, t: float, nodes: NDArray[np.int64], g: NDArray[np.float64]) -> None:
        """Show the newer of ``g`` for distinct ``nodes`` (compiled: for a node already
        shown, close its sawtooth piece ``[acc, t]`` and count the peak; for a first
        state, open its window), the same operations as the numpy expressions of
        :meth:`_update_one` over the nodes, the peaks summed as ``np.sum`` does."""
        from sigma_des.metrics.tick_kernels import aoi_apply  # numba: imported on first use

        if self._peaks.shape[0] < nodes.shape[0]:
            self._peaks = np.empty(nodes.shape[0])
        k, s = aoi_apply(float(t), nodes, g, self._gen, self._acc, self._start, self._area,
                         self.t_start, self._peaks)
        if k < 0:
            raise IndexError(f"node {nodes[-1 - k]} is out of range for {self.n} nodes")
        if k and t >= self.t_start:
            self._peak_sum += s
            self._peak_count += k

    def _update_one(self, t: float, node: int, gen_time: ArrayLike) -> None:
        """Scalar fast path of :meth:`update` (same arithmetic, Python floats)."""
        g = float(np.asarray(gen_time).ravel()[0])
        old = float(self._gen[node])
        if old == old:  # a state is shown
            if not g > old:
                return
            a = float(self._acc[node])
            dt = max(t - a, 0.0)
            self._area[node] += dt * ((t + a) * 0.5 - old)
            self._acc[node] = max(a, t)
            if t >= self.t_start:
                self._peak_sum += t - old
                self._peak_count += 1
        else:
            if g != g:
                return
            begin = max(t, self.t_start)
            self._acc[node] = begin
            self._start[node] = begin
        self._gen[node] = g

    def current(self, t: float) -> NDArray[np.float64]:
        """AoI of every node at time ``t`` (NaN for nodes never shown)."""
        return t - self._gen

    def finish(self, t_end: float) -> dict[str, float]:
        """Close the window at ``t_end`` and report (the tracker is not modified).

        Returns:
            ``time_average`` (s; NaN if no node time), ``peak_mean`` (s; NaN if
            no peaks), ``peak_count``, ``nodes`` (nodes contributing) and
            ``node_time`` (total length of their intervals, s).
        """
        if t_end < self._last_t:
            raise ValueError(f"t_end {t_end} precedes the last update at {self._last_t}")
        shown = ~np.isnan(self._gen)
        a = self._acc[shown]
        dt = np.maximum(t_end - a, 0.0)
        area = float(np.sum(self._area[shown] + dt * ((t_end + a) * 0.5 - self._gen[shown])))
        node_time = float(np.sum(np.maximum(t_end - self._start[shown], 0.0)))
        pc = self._peak_count
        return {
            "time_average": area / node_time if node_time > 0.0 else math.nan,
            "peak_mean": self._peak_sum / pc if pc else math.nan,
            "peak_count": pc,
            "nodes": int(shown.sum()),
            "node_time": node_time,
        }
