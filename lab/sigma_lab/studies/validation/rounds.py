"""The round of a frame at a missed knee, live against the DES, stage by stage.

Where the DES's knee and live's differ, some sizes of live's grid hold on one side and
not on the other (:func:`disputed`). For each such size, each of its live runs and the
calibrated DES (the per-message engine, with a recording tap), every frame issued in
the metrics window is split into its stages (ms, means over the frame's states):

* ``trigger``: the trigger's issue -> its receipt at a node (``trigger_p90``);
* ``job``: that receipt -> the node's state record (its publish call);
* ``up``: the record -> the server's receipt (``up_p90``);
* ``round``: the issue -> the frame's last state received (Lock-Step's barrier);
* ``period``: the mean time between issues (1000 / trigger rate).

The reading names the stage whose DES-minus-live difference is the largest: where
the DES's extra (or missing) time in the round comes from. Rows: ``rounds.csv``.
"""

from __future__ import annotations

import gzip
import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import Scenario
from sigma_des.events.cohort import execute
from sigma_des.events.tap import Tap
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.tables import md_table
from sigma_lab.studies.validation.grid import Cell, Plan

__all__ = ["ROUND_COLUMNS", "STAGES", "des_round", "disputed", "live_round", "round_md",
           "round_rows", "round_stages"]

#: The stages of a round, in order (ms).
STAGES = ("trigger", "job", "up", "round", "period")
#: ``rounds.csv``'s columns: the size and run, the stages, two tails, the frames split.
ROUND_COLUMNS = ("mode", "method", "nodes", "cell", "side", *STAGES, "trigger_p90", "up_p90",
                 "frames")


def round_stages(issue: pd.Series, trig: pd.DataFrame, states: pd.DataFrame, w0: float,
                 w1: float) -> dict[str, float]:
    """A run's round split into :data:`STAGES` (ms) over the frames issued in ``[w0, w1)``.

    Args:
        issue: frame -> the trigger's issue time (s).
        trig: ``node``, ``frame``, ``t_recv``: a trigger's receipt at a node (the first
            of a node's receipts of a frame counts).
        states: ``node``, ``frame``, ``t_rec`` (the state's record), ``t_recv`` (the
            server's receipt; the first of a node's receipts of a frame counts).
        w0: start of the window (s).
        w1: its end (s).
    """
    iss = issue.sort_index()
    iss = iss[(iss >= w0) & (iss < w1)]
    tr = trig.groupby(["node", "frame"], as_index=False).t_recv.min()
    tr = tr[tr.frame.isin(iss.index)]
    st = states.groupby(["node", "frame"], as_index=False).agg(t_rec=("t_rec", "min"),
                                                              t_recv=("t_recv", "min"))
    st = st[st.frame.isin(iss.index)]
    trig_ms = (tr.t_recv.to_numpy() - iss.reindex(tr.frame).to_numpy()) * 1e3
    both = st.merge(tr.rename(columns={"t_recv": "t_trig"}), on=["node", "frame"])
    job_ms = (both.t_rec - both.t_trig).to_numpy() * 1e3
    up_ms = (st.t_recv - st.t_rec).to_numpy() * 1e3
    last = st.groupby("frame").t_recv.max()
    round_ms = (last.to_numpy() - iss.reindex(last.index).to_numpy()) * 1e3
    gaps = np.diff(iss.to_numpy()) * 1e3

    def mean(x: Any) -> float:
        return float(np.mean(x)) if len(x) else math.nan

    def p90(x: Any) -> float:
        return float(np.percentile(x, 90)) if len(x) else math.nan

    return {"trigger": mean(trig_ms), "job": mean(job_ms), "up": mean(up_ms),
            "round": mean(round_ms), "period": mean(gaps), "trigger_p90": p90(trig_ms),
            "up_p90": p90(up_ms), "frames": float(len(iss))}


def live_round(messages: Path, method: str, w0: float, w1: float) -> dict[str, float]:
    """:func:`round_stages` of one method of a live run's ``messages.csv.gz``: the issue
    is the trigger's stamp, a node's receipt the time its job accepted the trigger (its
    ``state_pub`` row), the record a state's send time."""
    with gzip.open(messages, "rt") as fh:
        x = pd.read_csv(fh, usecols=["method", "kind", "node", "frame", "t_send", "t_recv",
                                     "t_trig", "republish"])
    x = x[x.method == method]
    issue = x[x.kind == "trigger"].groupby("frame").t_send.min()
    pub = x[x.kind == "state_pub"]
    trig = pd.DataFrame({"node": pub.node, "frame": pub.frame, "t_recv": pub.t_trig})
    st = x[(x.kind == "state") & ~x.republish.astype(bool)]
    states = pd.DataFrame({"node": st.node, "frame": st.frame, "t_rec": st.t_send,
                           "t_recv": st.t_recv})
    return round_stages(issue, trig, states, w0, w1)


class _RoundTap(Tap):
    """Keeps what :func:`round_stages` needs from a DES run."""

    def __init__(self) -> None:
        self.issues: dict[int, float] = {}
        self.trig: list[tuple[int, int, float]] = []
        self.rows: list[tuple[int, int, float, float]] = []

    def issue(self, frame: int, t_send: float) -> None:
        self.issues.setdefault(frame, t_send)

    def trigger(self, node: int, frame: int, t_send: float, t_recv: float) -> None:
        if node >= 0:
            self.trig.append((node, frame, t_recv))

    def states(self, t_recv: Any, nodes: Any, frames: Any, gens: Any, obs: Any) -> None:
        self.rows.extend(zip(map(int, nodes), map(int, frames), map(float, gens),
                               map(float, t_recv), strict=True))


def des_round(sc: Scenario, method: str) -> dict[str, float]:
    """:func:`round_stages` of ``method`` in the DES of scenario ``sc`` (run on the
    per-message engine, which reports every trigger receipt; the record is the state's
    generation time, the moment its node published it)."""
    sc = replace(sc, engine="events")
    tap = _RoundTap()
    execute(sc.run_spec(), method, lambda: make_dynamics(sc), lambda: make_behaviour(sc),
            None, lambda: tap)
    issue = pd.Series(tap.issues, dtype=float)
    trig = pd.DataFrame(tap.trig, columns=["node", "frame", "t_recv"])
    states = pd.DataFrame(tap.rows, columns=["node", "frame", "t_rec", "t_recv"])
    return round_stages(issue, trig, states, sc.warmup, sc.duration)


def disputed(knee: dict[str, Any], sizes: Sequence[int]) -> list[int]:
    """The sizes of live's grid ``sizes`` that hold on one side only: above the smaller
    of the two capacities, up to the larger (a side with no capacity holds nothing)."""
    lo, hi = sorted((int(knee["live_capacity"] or 0), int(knee["des_capacity"] or 0)))
    return [n for n in sorted(sizes) if lo < n <= hi]


def round_rows(plan: Plan, knees: list[dict[str, Any]], points: dict[str, list[Cell]],
               runs_of: Callable[[Cell], list[str]], scenario_of: Callable[[Cell], Scenario],
               out: Path) -> list[dict[str, Any]]:
    """The rows of ``rounds.csv``: for each missed knee, each disputed size's live runs
    and its DES.

    Args:
        plan: the suite's plan (window).
        knees: ``knee.csv``'s rows.
        points: per mode, live's knee grid (one cell per size).
        runs_of: cell -> the names of its live runs (folders under ``out/live``).
        scenario_of: cell -> the calibrated DES scenario prepared for it.
        out: the suite's output folder.
    """
    rows: list[dict[str, Any]] = []
    for k in knees:
        if k["verdict"] != "missed":
            continue
        grid = {c.nodes: c for c in points.get(k["mode"], [])}
        for n in disputed(k, list(grid)):
            cell = grid[n]
            base = {"mode": k["mode"], "method": k["method"], "nodes": n}
            for name in runs_of(cell):
                f = out / "live" / name / "messages.csv.gz"
                if f.exists():
                    rows.append({**base, "cell": name, "side": "live",
                                 **live_round(f, k["method"], plan.warmup, plan.duration)})
            rows.append({**base, "cell": cell.name, "side": "DES",
                         **des_round(scenario_of(cell), k["method"])})
    return rows


def _reading(group: list[dict[str, Any]]) -> str:
    """The stage with the largest DES-minus-live difference of a size (means of runs)."""
    live = [r for r in group if r["side"] == "live"]
    des = [r for r in group if r["side"] == "DES"]
    if not live or not des:
        return "no live run kept"
    diffs = {s: des[0][s] - float(np.mean([r[s] for r in live])) for s in STAGES[:3]}
    s = max(diffs, key=lambda x: abs(diffs[x]))
    rd = des[0]["round"] - float(np.mean([r["round"] for r in live]))
    return f"round {rd:+.2f} ms; most from `{s}` ({diffs[s]:+.2f} ms)"


def round_md(rows: list[dict[str, Any]], missed: bool) -> list[str]:
    """The section of ``summary.md``: nothing without a missed knee (``missed``), a line
    saying so when one was missed but no round could be split."""
    head = ["", "## The round at a missed knee (ms)", ""]
    if not rows:
        return [*head, "Not split: no calibration in the output folder's `cal/`."] if missed \
            else []
    lines = [*head,
             "Each frame of the sizes that hold on one side only, split: trigger issue -> "
             "receipt at a node (`trigger`), -> the node's state record (`job`), -> the "
             "server's receipt (`up`); `round` = issue -> the frame's last state received, "
             "`period` = time between issues. The reading: the DES's round against the "
             "mean of live's runs, and the stage that differs most.", ""]
    body, keys = [], []
    for r in rows:
        key = (r["mode"], r["method"], r["nodes"])
        reading = ""
        if key not in keys:
            keys.append(key)
            reading = _reading([x for x in rows
                                if (x["mode"], x["method"], x["nodes"]) == key])
        body.append([r["mode"], r["method"], str(r["nodes"]), r["cell"], r["side"],
                     *(f"{r[s]:.2f}" for s in (*STAGES, "trigger_p90", "up_p90")), reading])
    lines.append(md_table(["mode", "method", "N", "run", "side", *STAGES, "trigger p90",
                           "up p90", "reading"], body))
    return lines
