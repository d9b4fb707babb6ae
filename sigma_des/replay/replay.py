"""Rebuild every recorded node trajectory at a chosen rate (``sigma-des replay``).

The time axis of a node's trajectory is the generation time (``t_send``) of its
recorded states, one sample per frame (a repeated delivery of the same frame, e.g. a
QoS 1 duplicate or a Lock-Step re-publication, is the same sample and is dropped).
The output grid is ``k / rate`` for every ``k`` inside the node's recorded span.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from sigma_des.record.reader import RecordError, StateTable, read_states
from sigma_des.replay.interpolate import MIN_SAMPLES, interpolate, slerp_attitude
from sigma_des.replay.window import WindowRule

__all__ = ["REPLAY_COLUMNS", "node_samples", "replay"]

REPLAY_COLUMNS = ("method", "node", "t", "x", "y", "z", "phi", "theta", "psi")


def node_samples(st: StateTable, node: int) -> tuple[np.ndarray, ...]:
    """One node's samples ordered by frame, duplicates of a frame dropped.

    Returns:
        ``(frame, t, pos, vel, att)``.
    """
    rows = np.flatnonzero(st.node == node)
    order = rows[np.argsort(st.frame[rows], kind="stable")]
    fr = st.frame[order]
    keep = order[np.r_[True, fr[1:] != fr[:-1]]]
    return st.frame[keep], st.t_send[keep], st.pos[keep], st.vel[keep], st.att[keep]


def replay(
    path: str | Path,
    rate: float,
    method: str = "hermite-dw",
    methods: list[str] | None = None,
    window: WindowRule | None = None,
) -> pd.DataFrame:
    """Every node's trajectory of every recorded method, resampled at ``rate`` Hz.

    Args:
        path: the recording.
        rate: output rate (Hz, > 0).
        method: interpolation method (see :data:`~sigma_des.replay.INTERP_METHODS`).
        methods: recorded alignment methods to replay (default: all).
        window: the dynamic-window rule (``hermite-dw``); default ``rule="none"``: the
            simulator records exact states, and on noise-free samples any tangent window
            only adds bias (see docs/REPLAY.md).

    Returns:
        Tidy rows :data:`REPLAY_COLUMNS` (NED m, rad).

    Raises:
        RecordError: unreadable file, a node with fewer states than ``method`` needs,
            or timestamps that do not increase with the frame.
        ValueError: ``rate`` <= 0 or unknown method.
    """
    if not (rate > 0 and math.isfinite(rate)):
        raise ValueError(f"rate must be a finite number > 0 Hz, got {rate}")
    if method not in MIN_SAMPLES:
        raise ValueError(f"unknown method {method!r}; allowed: {', '.join(MIN_SAMPLES)}")
    window = window or WindowRule(rule="none")
    tables = read_states(path)
    parts: list[pd.DataFrame] = []
    for m, st in tables.items():
        if methods is not None and m not in methods:
            continue
        for node in np.unique(st.node).tolist():
            parts.append(_node(path, m, st, int(node), rate, method, window))
    if not parts:
        return pd.DataFrame({c: [] for c in REPLAY_COLUMNS})
    return pd.concat(parts, ignore_index=True)


def _node(path: str | Path, m: str, st: StateTable, node: int, rate: float, method: str,
          window: WindowRule | None) -> pd.DataFrame:
    fr, t, pos, vel, att = node_samples(st, node)
    need = MIN_SAMPLES[method]
    if t.size < need:
        raise RecordError(str(path), f"{m} node {node}: {t.size} recorded states, "
                          f"method {method} needs at least {need}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        j = int(bad[0]) + 1
        raise RecordError(str(path), f"{m} node {node}: timestamps not increasing "
                          f"(frame {int(fr[j])} at t = {float(t[j])!r} after frame "
                          f"{int(fr[j - 1])} at t = {float(t[j - 1])!r})")
    k0, k1 = math.ceil(t[0] * rate - 1e-9), math.floor(t[-1] * rate + 1e-9)
    grid = np.arange(k0, k1 + 1) / rate
    grid = grid[(grid >= t[0]) & (grid <= t[-1])]
    try:
        p = interpolate(t, pos, method=method, at=grid, velocities=vel, attitudes=att,
                        window=window)
        a = slerp_attitude(t, att, grid)
    except ValueError as e:  # e.g. non-finite recorded values
        raise RecordError(str(path), f"{m} node {node}: {e}") from None
    return pd.DataFrame({"method": m, "node": node, "t": grid, "x": p[:, 0], "y": p[:, 1],
                         "z": p[:, 2], "phi": a[:, 0], "theta": a[:, 1], "psi": a[:, 2]})
