"""Where a live state's latency goes near capacity: the server's receive path, per run.

A kept live run (``live/<cell>/``: ``messages.csv.gz``, ``cpu.csv``, ``summary.json``)
holds, per method, what this module turns into one row of figures:

* ``records_per_publish``: state records over state PUBLISHes the server received (its
  ledger's PUBLISHes less the triggers and command PUBLISHes it sent; a Lock-Step
  re-request counts as a state PUBLISH): the live bundle size;
* the server's loop: wake-ups per second, calls per wake-up, loop CPU and busy wall time
  per wake-up, and the process's run-queue wait per CPU second;
* ``trigger_late_*``: how late the server's loop ran its trigger timers (issue time less
  ``frame / f_trig``, less its 1st percentile; free-running methods only): a loop that
  runs its timers late is behind;
* the state latency (mean, p99) and its mean per quartile of receipt rank within a frame.

With the live impairment shim on (any link latency), the server stamps a state's
receipt when its loop runs the shim's timer for it (``live/server.py``), so the state
latency holds the loop's own waits. A state latency far above the trigger timers'
lateness says the states waited before the loop got them. ``experiments/live_path.py``
prints the table for a kept campaign.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["PATH_COLUMNS", "path_md", "path_rows", "rank_quartiles", "trigger_lateness"]

#: Columns of a row of :func:`path_rows`.
PATH_COLUMNS = ("cell", "method", "records", "records_per_publish", "server_wakes_hz",
                "calls_per_wake", "loop_cpu_per_wake_ms", "loop_wall_per_wake_ms",
                "server_runq_per_cpu", "latency_ms", "latency_p99_ms", "trigger_latency_ms",
                "trigger_late_ms", "trigger_late_p99_ms", "rank_q1_ms", "rank_q2_ms",
                "rank_q3_ms", "rank_q4_ms")


def trigger_lateness(issue: np.ndarray, frame: np.ndarray, f_trig: float) -> np.ndarray:
    """Seconds each trigger was issued after ``frame / f_trig``, less the 1st percentile
    of that delay (the loop's fixed offset from the run's time origin)."""
    late = np.asarray(issue, dtype=float) - np.asarray(frame, dtype=float) / f_trig
    return late - float(np.quantile(late, 0.01)) if late.size else late


def rank_quartiles(frame: np.ndarray, t_recv: np.ndarray, latency: np.ndarray
                   ) -> list[float]:
    """Mean latency of the states in each quartile of their receipt rank within their
    frame (rank 1 = the frame's first receipt; quartiles of the largest frame's count)."""
    df = pd.DataFrame({"frame": frame, "t": t_recv, "lat": latency})
    if df.empty:
        return [math.nan] * 4
    rank = df.groupby("frame")["t"].rank(method="first").to_numpy()
    n = float(df.groupby("frame").size().max())
    edges = [0.0, n / 4, n / 2, 3 * n / 4, n]
    lat = df["lat"].to_numpy()
    return [float(lat[(rank > lo) & (rank <= hi)].mean()) if np.any((rank > lo) & (rank <= hi))
            else math.nan for lo, hi in zip(edges[:-1], edges[1:], strict=True)]


def _row(cell: str, method: str, d: pd.DataFrame, srv: pd.Series, warmup: float,
         f_trig: float, bundle: bool) -> dict[str, Any]:
    """One method's figures (``d``: its message rows; ``srv``: its server CPU row)."""
    w = float(srv["window_s"])
    lo, hi = warmup, warmup + w
    sent = d[d["kind"] == "trigger_sent"]
    sent = sent[(sent["t_send"] >= lo) & (sent["t_send"] < hi)]
    cmd = d[(d["kind"] == "command") & (d["t_send"] >= lo) & (d["t_send"] < hi)]
    cmd_pub = cmd.groupby(["host", "frame"]).ngroups if bundle else len(cmd)
    st = d[(d["kind"] == "state") & (d["t_send"] >= lo) & (d["t_send"] < hi)]
    state_pub = float(srv["messages"]) - len(sent) - cmd_pub
    lat = (st["t_recv"] - st["t_send"]).to_numpy() * 1e3
    trig = d[(d["kind"] == "trigger") & (d["t_send"] >= lo) & (d["t_send"] < hi)]
    late = (trigger_lateness(sent["t_send"].to_numpy(), sent["frame"].to_numpy(), f_trig)
            * 1e3 if method != "lockstep" else np.zeros(0))
    wakes = float(srv["wakes"])
    q = rank_quartiles(st["frame"].to_numpy(), st["t_recv"].to_numpy(), lat)
    return {
        "cell": cell, "method": method, "records": len(st),
        "records_per_publish": len(st) / state_pub if state_pub > 0 else math.nan,
        "server_wakes_hz": wakes / w, "calls_per_wake": float(srv["calls"]) / wakes,
        "loop_cpu_per_wake_ms": float(srv["loop_cpu_s"]) / wakes * 1e3,
        "loop_wall_per_wake_ms": float(srv["loop_wall_s"]) / wakes * 1e3,
        "server_runq_per_cpu": float(srv["runq_wait_s"]) / float(srv["cpu_s"]),
        "latency_ms": float(lat.mean()) if lat.size else math.nan,
        "latency_p99_ms": float(np.quantile(lat, 0.99)) if lat.size else math.nan,
        "trigger_latency_ms": float((trig["t_recv"] - trig["t_send"]).mean() * 1e3),
        "trigger_late_ms": float(late.mean()) if late.size else math.nan,
        "trigger_late_p99_ms": float(np.quantile(late, 0.99)) if late.size else math.nan,
        **{f"rank_q{i + 1}_ms": v for i, v in enumerate(q)},
    }


def path_rows(run: Path, cell: str) -> list[dict[str, Any]]:
    """The figures of every method of the kept live run in ``run`` (one row each)."""
    summary = json.loads((run / "summary.json").read_text())
    sc = summary["scenario"]
    cpu = pd.read_csv(run / "cpu.csv")
    msgs = pd.read_csv(run / "messages.csv.gz")
    rows = []
    for method, d in msgs.groupby("method", sort=False):
        srv = cpu[(cpu["method"] == method) & (cpu["process"] == "server")]
        if srv.empty:
            continue
        bundle = bool(summary["live"][str(method)].get("bundle", False))
        rows.append(_row(cell, str(method), d, srv.iloc[0], float(sc["warmup"]),
                         float(sc["f_trig"]), bundle))
    return rows


def path_md(rows: list[dict[str, Any]]) -> list[str]:
    """A markdown table of :func:`path_rows` rows (3 significant digits)."""
    head = "| " + " | ".join(PATH_COLUMNS) + " |"
    out = [head, "|" + "---|" * len(PATH_COLUMNS)]
    for r in rows:
        out.append("| " + " | ".join(f"{r[c]:.3g}" if isinstance(r[c], float) else str(r[c])
                                     for c in PATH_COLUMNS) + " |")
    return out
