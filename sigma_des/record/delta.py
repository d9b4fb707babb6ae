"""Incremental state storage: per-node delta encoding with a dead-band and keyframes.

The replay memory of the reference paper stores only *changes*. Here each node's
recorded stream is a sequence of rows: a **keyframe** holds the absolute state;
any other row holds the change since the node's previous recorded row (rounded to
``decimals`` places, which keeps the JSON short). A state is **not recorded** when
it is inside the dead-band: its position within ``deadband_pos`` metres of the
dead-reckoned position (previous recorded position + velocity × elapsed generation
time), its velocity within ``deadband_vel`` m/s and its attitude within
``deadband_att`` rad of the previous recorded row — unless a keyframe is due
(``keyframe_every`` frames since the node's last keyframe, or its first state).

The decoder repeats the encoder's floating point additions in the same order, so
the reconstructed rows are bit-identical to what the encoder believed it wrote.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["DeltaEncoder", "decode"]

_F = NDArray[np.float64]
_I = NDArray[np.int64]


class DeltaEncoder:
    """Encoder state of one method's state stream.

    Args:
        deadband_pos: dead-band on the dead-reckoned position error (m); 0 records all.
        deadband_vel: dead-band on the velocity change (m/s).
        deadband_att: dead-band on the attitude change (rad, largest Euler angle).
        keyframe_every: frames between a node's keyframes (>= 1).
        decimals: delta rows are rounded to this many decimal places.
    """

    def __init__(
        self,
        deadband_pos: float,
        deadband_vel: float,
        deadband_att: float,
        keyframe_every: int,
        decimals: int = 6,
    ) -> None:
        self.db = (deadband_pos, deadband_vel, deadband_att)
        self.every = keyframe_every
        self.decimals = decimals
        self._n = 0
        self.last = np.zeros((0, 9))  # reconstructed pos, vel, att per node
        self.last_t = np.zeros(0)
        self.key_frame = np.zeros(0, dtype=np.int64)
        self.seen = 0
        self.written = 0

    def _grow(self, n: int) -> None:
        if n <= self._n:
            return
        m = max(n, 2 * self._n)
        last = np.zeros((m, 9))
        last[: self._n] = self.last
        lt = np.zeros(m)
        lt[: self._n] = self.last_t
        kf = np.full(m, -1, dtype=np.int64)
        kf[: self._n] = self.key_frame
        self.last, self.last_t, self.key_frame, self._n = last, lt, kf, m

    def encode(
        self, nodes: _I, frames: _I, t_send: _F, values: _F
    ) -> tuple[NDArray[np.intp], NDArray[np.int8], _F]:
        """Encode a batch of states (rows of ``values``: pos, vel, att; 9 columns).

        Rows of the same node are taken in batch order.

        Returns:
            ``(rows, key, out)``: indices of the recorded rows in output order, their
            keyframe flags and their encoded values (absolute or delta).
        """
        self.seen += nodes.size
        if nodes.size == 0:
            return np.zeros(0, np.intp), np.zeros(0, np.int8), np.zeros((0, 9))
        self._grow(int(nodes.max()) + 1)
        out_rows: list[NDArray[np.intp]] = []
        out_key: list[NDArray[np.int8]] = []
        out_val: list[_F] = []
        remaining = np.arange(nodes.size)
        while remaining.size:  # one round per occurrence: each node at most once a round
            _u, first = np.unique(nodes[remaining], return_index=True)
            first.sort()
            take = remaining[first]
            mask = np.ones(remaining.size, dtype=bool)
            mask[first] = False
            remaining = remaining[mask]
            r, k, v = self._round(nodes[take], frames[take], t_send[take], values[take])
            out_rows.append(take[r])
            out_key.append(k)
            out_val.append(v)
        rows = np.concatenate(out_rows)
        self.written += rows.size
        return rows, np.concatenate(out_key), np.concatenate(out_val)

    def _round(
        self, nd: _I, fr: _I, ts: _F, val: _F
    ) -> tuple[NDArray[np.intp], NDArray[np.int8], _F]:
        """Encode rows of distinct nodes (vectorised)."""
        kf = self.key_frame[nd]
        key = (kf < 0) | (fr - kf >= self.every) | (fr < kf)
        last = self.last[nd]
        dt = ts - self.last_t[nd]
        pred = last[:, 0:3] + last[:, 3:6] * dt[:, None]
        e_pos = np.linalg.norm(val[:, 0:3] - pred, axis=1)
        e_vel = np.linalg.norm(val[:, 3:6] - last[:, 3:6], axis=1)
        d_att = val[:, 6:9] - last[:, 6:9]
        e_att = np.abs((d_att + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        db_p, db_v, db_a = self.db
        write = key | (e_pos > db_p) | (e_vel > db_v) | (e_att > db_a)
        rows = np.flatnonzero(write)
        k = key[rows]
        v = val[rows].copy()
        w_nd = nd[rows]
        delta = np.round(v[~k] - last[rows][~k], self.decimals)
        new_last = v.copy()
        new_last[~k] = last[rows][~k] + delta
        v[~k] = delta
        self.last[w_nd] = new_last
        self.last_t[w_nd] = ts[rows]
        self.key_frame[w_nd[k]] = fr[rows][k]
        return rows, k.astype(np.int8), v


def decode(nodes: _I, key: NDArray[np.int8], values: _F) -> _F:
    """Absolute values of delta-encoded rows given in recorded order.

    Args:
        nodes: node of each row.
        key: 1 where the row is a keyframe.
        values: the encoded values (absolute on keyframes, deltas otherwise).

    Returns:
        The reconstructed absolute values, row for row (bit-identical to the
        encoder's running values).

    Raises:
        ValueError: a node's first row is not a keyframe.
    """
    out = np.empty_like(values)
    if nodes.size == 0:
        return out
    order = np.argsort(nodes, kind="stable")
    nd = nodes[order]
    k = key[order].astype(bool)
    starts = np.r_[True, nd[1:] != nd[:-1]]
    if np.any(starts & ~k):
        bad = int(nd[np.flatnonzero(starts & ~k)[0]])
        raise ValueError(f"node {bad}: the first recorded state is not a keyframe")
    v = values[order]
    res = v.copy()
    # position of each row within its keyframe segment (node starts are keyframes)
    first = np.flatnonzero(k)
    seg_start = first[np.cumsum(k) - 1]
    offset = np.arange(v.shape[0]) - seg_start
    # res[r] = res[r - 1] + v[r] along each segment, one offset at a time for all
    # segments at once: the encoder's additions, in the encoder's order
    rows_by_offset = np.argsort(offset, kind="stable")
    counts = np.bincount(offset)
    pos = np.cumsum(counts)
    for o in range(1, counts.size):
        r = rows_by_offset[pos[o - 1] : pos[o]]
        res[r] = res[r - 1] + v[r]
    out[order] = res
    return out
