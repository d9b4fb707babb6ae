"""In-sample check of a calibration: the calibrated DES re-predicting its own live run.

``sigma-des calibrate`` runs the calibrated scenario (the live run's own scenario,
seed and window) through the DES for every method of the live run and sets the DES
figures next to the live ones (``summary.json``):

* mean and p99 AoI, mean state and trigger latency, achieved trigger rate: relative
  error ``(DES - live) / live`` (live, a trigger's latency is taken per receiving host
  from ``messages.csv.gz``; the DES's per receiving node);
* missed-frame fraction (node x frame states of the window's triggers that never
  reached the server, the live runner's definition, :func:`missed_frac`): the
  difference in percentage points, since live often misses none.

A cell whose error exceeds :data:`TOLERANCE` (10 %, or 10 percentage points) is
flagged: a fit that cannot reproduce the run it was fitted to says so.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import Scenario
from sigma_des.errors import ConfigError

__all__ = ["IN_SAMPLE_METRICS", "TOLERANCE", "in_sample", "live_trigger_latency", "missed_frac",
           "apart_text", "repeats_apart"]

#: Metrics compared, in report order.
IN_SAMPLE_METRICS = ("aoi_mean", "aoi_p99", "latency_state_mean", "latency_trigger_mean",
                     "trigger_rate_hz", "missed_frac")
#: Largest error not flagged (relative; percentage points / 100 for ``missed_frac``).
TOLERANCE = 0.10


def missed_frac(table: pd.DataFrame, nodes: int, warmup: float, duration: float) -> float:
    """Share of the node x frame states of the window's triggers that never arrived.

    Args:
        table: a recording's table (``sigma_des.record.read_table``): ``trigger`` rows
            (``frame``, ``t_send``: the issue, or every delivery) and ``state`` rows.
        nodes: number of nodes.
        warmup: the window starts here (s).
        duration: and ends here (s).

    Returns:
        ``1 - delivered / (triggers x nodes)``; NaN without a trigger in the window.
    """
    # a frame's issue is its first trigger row (the cohort engine writes the issue, node
    # -1; the per-message engine every delivery, re-requests later with the same frame)
    first = table[table["kind"] == "trigger"].groupby("frame")["t_send"].min()
    frames = set(first[(first >= warmup) & (first < duration)].index.astype(int).tolist())
    if not frames:
        return math.nan
    st = table[table["kind"] == "state"]
    got = st[st["frame"].astype(int).isin(frames)].drop_duplicates(["node", "frame"])
    return 1.0 - len(got) / (len(frames) * nodes)


def _des_figures(sc: Scenario, method: str) -> dict[str, float]:
    from sigma_des.api import run_method
    from sigma_des.record import read_table

    with tempfile.TemporaryDirectory(prefix="sigma-des-insample-") as d:
        rec = Path(d) / "run.mcap"
        m = run_method(sc, method, record=rec)["metrics"]
        table = read_table(rec)
    out = {k: float(m[k]) if m[k] is not None else math.nan for k in IN_SAMPLE_METRICS[:-1]}
    out["missed_frac"] = missed_frac(table, sc.nodes, sc.warmup, sc.duration)
    return out


def live_trigger_latency(source: Path, sc: Scenario) -> dict[str, float]:
    """Mean trigger latency (ms) per method, from the live run's message table."""
    from sigma_des.calibrate.messages import read_messages

    try:
        t = read_messages(source)
    except ConfigError:  # no table: the cell stays NaN (not compared)
        return {}
    t = t[(t["kind"] == "trigger") & (t["t_send"] >= sc.warmup) & (t["t_send"] < sc.duration)]
    lat = (t["t_recv"] - t["t_send"]) * 1000.0
    return {str(m): float(v) for m, v in lat.groupby(t["method"]).mean().items()}


def _error(metric: str, live: float, des: float) -> float:
    if metric == "missed_frac":
        return des - live
    if not (math.isfinite(live) and math.isfinite(des)) or live == 0.0:
        return math.nan
    return (des - live) / live


def in_sample(sc: Scenario, source: Path) -> tuple[list[dict[str, Any]], list[str]]:
    """Run the calibrated ``sc`` for every method of the live run at ``source``.

    Args:
        sc: the calibrated scenario (the live run's scenario, seed and window).
        source: the live ``--out`` directory (its ``summary.json`` holds the live figures).

    Returns:
        Rows ``method, metric, live, des, error, flagged`` (``error`` relative, in
        percentage points / 100 for ``missed_frac``; NaN where undefined) and
        warnings (no summary to compare with, or flagged cells).
    """
    summ = (source if source.is_dir() else source.parent) / "summary.json"
    if not summ.exists():
        return [], [f"no summary.json next to {source}: in-sample check skipped"]
    d = json.loads(summ.read_text())
    rows: list[dict[str, Any]] = []
    warn: list[str] = []
    trig = live_trigger_latency(source, sc)
    for method, live_m in d.get("methods", {}).items():
        des = _des_figures(sc, method)
        for k in IN_SAMPLE_METRICS:
            v = live_m.get(k)
            if v is None and k == "latency_trigger_mean":
                v = trig.get(method)
            live = float(v) if v is not None else math.nan
            err = _error(k, live, des[k])
            flag = bool(np.isfinite(err) and abs(err) > TOLERANCE)
            rows.append({"method": method, "metric": k, "live": live, "des": des[k],
                         "error": err, "flagged": flag})
        bad = [r["metric"] for r in rows if r["method"] == method and r["flagged"]]
        if bad:
            warn.append(f"{method}: the calibrated DES misses its own run by more than "
                        f"{TOLERANCE:.0%} on {', '.join(bad)}")
    return rows, warn


def repeats_apart(report: dict[str, Any]) -> list[dict[str, Any]]:
    """Where no calibration can be within :data:`TOLERANCE` of every run: live's own
    repeats of one setting (the runs' size, hosts and message mode) that disagree on a
    method's metric by more than ``(1 + TOLERANCE) / (1 - TOLERANCE)`` (22 %; for missed
    frames by more than ``2 * TOLERANCE``, 20 pp). No one value is within the tolerance
    of each of them, and the DES predicts a setting alike whichever run it is (up to
    the run's seed).

    Args:
        report: a calibration's report: its ``in_sample`` rows (with ``run``) and
            ``runs`` (each run's ``nodes``, ``hosts`` and ``bundle``).

    Returns:
        One row per such setting x method x metric, in report order: ``setting``,
        ``method``, ``metric``, ``runs``, ``live`` (the repeats' values), ``apart``
        (``max / min - 1``; ``max - min`` for ``missed_frac``) and ``flagged`` (how many
        of the group's cells the check flagged).
    """
    runs = report.get("runs", {})
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in report.get("in_sample", []):
        info = runs.get(r.get("run"))
        if info is None or not math.isfinite(r["live"]):
            continue
        mode = "bundled" if info.get("bundle") else "per node"
        setting = f"N = {info['nodes']}, {info['hosts']} hosts, {mode}"
        groups.setdefault((setting, r["method"], r["metric"]), []).append(r)
    out = []
    for (setting, method, metric), rows in groups.items():
        live = [float(r["live"]) for r in rows]
        lo, hi = min(live), max(live)
        if len(rows) < 2 or (metric != "missed_frac" and lo <= 0.0):
            continue
        if metric == "missed_frac":
            apart, too = hi - lo, hi - lo > 2 * TOLERANCE
        else:
            apart, too = hi / lo - 1.0, hi / lo > (1 + TOLERANCE) / (1 - TOLERANCE)
        if too:
            out.append({"setting": setting, "method": method, "metric": metric,
                        "runs": [r["run"] for r in rows], "live": live, "apart": apart,
                        "flagged": sum(bool(r["flagged"]) for r in rows)})
    return out


def apart_text(group: dict[str, Any]) -> str:
    """One :func:`repeats_apart` row in words, as both reports print it: the setting,
    the method and metric, live's repeats and how far apart they are."""
    size = (f"{100 * group['apart']:.0f} pp" if group["metric"] == "missed_frac"
            else f"{100 * group['apart']:.0f} %")
    return (f"{group['setting']}, {group['method']} {group['metric']}: "
            f"{' / '.join(f'{v:.4g}' for v in group['live'])} ({size})")
