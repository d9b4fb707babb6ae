"""Rebuild every recorded node trajectory at a chosen rate (``sigma-des replay``).

The time axis of a node's trajectory is the generation time (``t_send``) of its
recorded states, one sample per frame (a repeated delivery of the same frame, e.g. a
QoS 1 duplicate or a Lock-Step re-publication, is the same sample and is dropped).
The output grid is ``k / rate`` for every ``k`` inside the node's recorded span.
Positions are interpolated per node; attitudes by slerp for all nodes at once.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.record.reader import RecordError, StateTable, read_states
from sigma_des.replay.interpolate import MIN_SAMPLES, interpolate, slerp_segments
from sigma_des.replay.window import WindowRule

__all__ = ["REPLAY_COLUMNS", "node_samples", "replay"]

REPLAY_COLUMNS = ("method", "node", "t", "x", "y", "z", "phi", "theta", "psi")


def _unique_samples(st: StateTable) -> NDArray[np.intp]:
    """Row indices ordered by (node, frame), the first delivery of each frame kept."""
    order = np.lexsort((np.arange(st.node.size), st.frame, st.node))
    nd, fr = st.node[order], st.frame[order]
    keep = np.r_[True, (nd[1:] != nd[:-1]) | (fr[1:] != fr[:-1])]
    return order[keep]


def node_samples(st: StateTable, node: int) -> tuple[NDArray[Any], ...]:
    """One node's samples ordered by frame, duplicates of a frame dropped.

    Returns:
        ``(frame, t, pos, vel, att)``.
    """
    rows = np.flatnonzero(st.node == node)
    order = rows[np.lexsort((np.arange(rows.size), st.frame[rows]))]
    fr = st.frame[order]
    keep = order[np.r_[True, fr[1:] != fr[:-1]]]
    return st.frame[keep], st.t_send[keep], st.pos[keep], st.vel[keep], st.att[keep]


def replay(
    path: str | Path,
    rate: float,
    method: str = "hermite-dw",
    methods: list[str] | None = None,
    window: WindowRule | None = None,
) -> Any:
    """Every node's trajectory of every recorded method, resampled at ``rate`` Hz.

    Args:
        path: the recording.
        rate: output rate (Hz, > 0).
        method: interpolation method (see :data:`~sigma_des.replay.INTERP_METHODS`).
        methods: recorded alignment methods to replay (default: all).
        window: the dynamic-window rule (``hermite-dw``); default ``rule="none"``: the
            simulator records exact states, and on noise-free samples any tangent window
            only adds bias (see docs/concepts/recording.md).

    Returns:
        A ``pandas.DataFrame`` of :data:`REPLAY_COLUMNS` (NED m, rad).

    Raises:
        RecordError: unreadable file, a node with fewer states than ``method`` needs,
            timestamps that do not increase with the frame, non-finite values.
        ValueError: ``rate`` <= 0 or unknown method.
    """
    import pandas as pd

    if not (rate > 0 and math.isfinite(rate)):
        raise ValueError(f"rate must be a finite number > 0 Hz, got {rate}")
    if method not in MIN_SAMPLES:
        raise ValueError(f"unknown method {method!r}; allowed: {', '.join(MIN_SAMPLES)}")
    window = window or WindowRule(rule="none")
    tables = read_states(path)
    parts: list[dict[str, Any]] = []
    for m, st in tables.items():
        if methods is None or m in methods:
            parts.append(_method(path, m, list(tables).index(m), st, rate, method, window))
    if not parts:
        return pd.DataFrame({c: [] for c in REPLAY_COLUMNS})
    cols: dict[str, Any] = {c: np.concatenate([p[c] for p in parts]) for c in REPLAY_COLUMNS}
    cols["method"] = pd.Categorical.from_codes(cols["method"], categories=list(tables))
    return pd.DataFrame(cols)


def _method(path: str | Path, m: str, code: int, st: StateTable, rate: float, method: str,
            window: WindowRule) -> dict[str, Any]:
    """All nodes of one recorded method."""
    idx = _unique_samples(st)
    nd, fr, t = st.node[idx], st.frame[idx], st.t_send[idx]
    pos, vel, att = st.pos[idx], st.vel[idx], st.att[idx]
    starts = np.flatnonzero(np.r_[True, nd[1:] != nd[:-1], True])
    grids, xyz, segs = [], [], []
    need = MIN_SAMPLES[method]
    for s, (a, b) in enumerate(zip(starts[:-1].tolist(), starts[1:].tolist(), strict=True)):
        node = int(nd[a])
        if b - a < max(need, 2):
            raise RecordError(str(path), f"{m} node {node}: {b - a} recorded states, "
                              f"method {method} needs at least {max(need, 2)}")
        ts = t[a:b]
        bad = np.flatnonzero(np.diff(ts) <= 0)
        if bad.size:
            j = a + int(bad[0]) + 1
            raise RecordError(str(path), f"{m} node {node}: timestamps not increasing "
                              f"(frame {int(fr[j])} at t = {float(t[j])!r} after frame "
                              f"{int(fr[j - 1])} at t = {float(t[j - 1])!r})")
        k0, k1 = math.ceil(ts[0] * rate - 1e-9), math.floor(ts[-1] * rate + 1e-9)
        grid = np.arange(k0, k1 + 1) / rate
        grid = grid[(grid >= ts[0]) & (grid <= ts[-1])]
        try:
            xyz.append(interpolate(ts, pos[a:b], method=method, at=grid, velocities=vel[a:b],
                                   attitudes=att[a:b], window=window))
            if not np.isfinite(att[a:b]).all():
                raise ValueError("times and samples must be finite (attitude)")
        except ValueError as e:  # e.g. non-finite recorded values
            raise RecordError(str(path), f"{m} node {node}: {e}") from None
        grids.append(grid)
        segs.append(np.full(grid.size, s, dtype=np.intp))
    q = np.concatenate(grids) if grids else np.zeros(0)
    seg = np.concatenate(segs) if segs else np.zeros(0, dtype=np.intp)
    p = np.concatenate(xyz) if xyz else np.zeros((0, 3))
    a3 = slerp_segments(t, att, starts, q, seg) if q.size else np.zeros((0, 3))
    return {"method": np.full(q.size, code, dtype=np.int16), "node": nd[starts[:-1]][seg], "t": q,
            "x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "phi": a3[:, 0], "theta": a3[:, 1],
            "psi": a3[:, 2]}
