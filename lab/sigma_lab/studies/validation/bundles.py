"""Bundled host PUBLISHes, live and DES: how many records one carries and what sets it.

A bundled host sends the states of one loop turn as one PUBLISH. Live, a turn is one
batch of the host loop's due timers (``live/host.py``: the first record of a turn
schedules the flush at its own time, which runs at the start of the loop's next
batch); in the DES the first record schedules the flush when the host process's loop
thread is next free (``net/network.py``), and what keeps that thread busy is the CPU
stage's bursts (their run, their run-queue wait, their wait for a core and, with
``lock_switch``, their wait for the process's network thread).

* :func:`live_turns` reconstructs a live host's turns from its ``state_pub`` rows
  (the time each job's completion ran on the loop): completions of one batch run a few
  µs apart, a flush and the next batch take longer than ``gap_s`` (60 µs: the
  reconstruction's mean records per PUBLISH then matches the server ledger's within
  ~10 % on the calibration, N = 30, 60 and 100 bundled cells);
* :func:`des_turns` runs the DES once and records every host flush and, for each
  host publish burst, where its thread time went (:class:`BurstWait`);
* :func:`turn_stats` summarises turns: records per PUBLISH (mean, histogram), PUBLISHes
  per second and host, the time between a host's consecutive PUBLISHes;
* :func:`live_lateness` is how late the live loop ran the completions of the jobs that
  started at a trigger's handling (the first ``cores_per_host`` nodes of a host);
* :func:`compare_rows` puts a kept campaign's live runs of a bundled cell (every copy)
  beside the DES's prediction of it from the campaign's calibration.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import Scenario

__all__ = ["BurstWait", "GAP_S", "compare_rows", "des_turns", "live_lateness", "live_turns",
           "turn_stats"]

#: Gap between two completions on a live host's loop that starts a new turn (s).
GAP_S = 60e-6


def live_turns(msgs: pd.DataFrame, method: str, lo: float, hi: float,
               gap_s: float = GAP_S) -> dict[int, list[tuple[float, int]]]:
    """Each live host's turns ``(time of the turn's first completion, records)`` in
    ``[lo, hi)``, from the ``state_pub`` rows of ``method`` (a run's
    ``messages.csv.gz``)."""
    d = msgs[(msgs["method"] == method) & (msgs["kind"] == "state_pub")
             & (msgs["t_send"] >= lo) & (msgs["t_send"] < hi)]
    out: dict[int, list[tuple[float, int]]] = {}
    for h, g in d.groupby("host"):
        t = np.sort(g["t_send"].to_numpy())
        new = np.r_[True, np.diff(t) > gap_s]
        sizes = np.bincount(np.cumsum(new))[1:]
        out[int(h)] = list(zip(t[new].tolist(), sizes.tolist(), strict=True))
    return out


def live_lateness(msgs: pd.DataFrame, method: str, lo: float, hi: float,
                  cores: int) -> np.ndarray:
    """Seconds the live loop ran a job's completion after it was due, for the jobs of
    each host's first ``cores`` nodes (they start when the trigger is handled: due at
    ``t_trig + cost``); rows whose trigger is not the job's own (a newer one accepted
    while it ran) are left out (negative or over 20 ms)."""
    d = msgs[(msgs["method"] == method) & (msgs["kind"] == "state_pub")
             & (msgs["t_send"] >= lo) & (msgs["t_send"] < hi)].copy()
    d["local"] = d.groupby("host")["node"].rank(method="dense").astype(int) - 1
    d = d[d["local"] < cores]
    late = (d["t_send"] - d["t_trig"] - d["cost"]).to_numpy()
    return late[(late > -50e-6) & (late < 0.02)]


def turn_stats(turns: dict[int, list[tuple[float, int]]], window: float) -> dict[str, Any]:
    """Records per PUBLISH (mean; histogram of 1..12 records), PUBLISHes per second and
    host, and the time between a host's consecutive PUBLISHes (ms: mean, median, 10th
    and 90th percentiles)."""
    sizes = np.array([k for ts in turns.values() for _t, k in ts], dtype=np.int64)
    gaps = np.concatenate([np.diff([t for t, _k in ts]) for ts in turns.values()
                           if len(ts) > 1] or [np.zeros(0)]) * 1e3
    q = np.quantile(gaps, [0.1, 0.5, 0.9]) if gaps.size else [np.nan] * 3
    return {
        "records_per_publish": float(sizes.mean()) if sizes.size else np.nan,
        "hist": np.bincount(sizes, minlength=13)[1:13].tolist(),
        "publish_hz_per_host": sizes.size / window / max(len(turns), 1),
        "gap_ms_mean": float(gaps.mean()) if gaps.size else np.nan,
        "gap_ms_p10": float(q[0]), "gap_ms_median": float(q[1]), "gap_ms_p90": float(q[2]),
    }


@dataclass
class BurstWait:
    """Where one host process's publish bursts spent their thread time (sums, s).

    Attributes:
        bursts: publish bursts arriving in the window.
        run: their run on a core.
        lock: their wait for the network thread (``lock_switch``).
        lock_unstarted: the part of ``lock`` before that network-thread burst started
            (the network thread was waiting for a core, not running).
        runq: their run-queue wait.
        core: their wait for a core after those.
    """

    bursts: int = 0
    run: float = 0.0
    lock: float = 0.0
    lock_unstarted: float = 0.0
    runq: float = 0.0
    core: float = 0.0
    net_starts: dict[float, float] = field(default_factory=dict)


@contextlib.contextmanager
def _instrumented(host: str, lo: float, hi: float) -> Iterator[
        tuple[list[tuple[int, float, int]], BurstWait]]:
    """Record every host flush ``(client, t, records)`` and the publish bursts of process
    ``host`` while the block runs (the classes are restored after it)."""
    from sigma_des.net import cpu as cpumod
    from sigma_des.net.network import Network

    flushes: list[tuple[int, float, int]] = []
    bw = BurstWait()
    proc_cls, net_cls = cpumod.Process, Network
    saved = (proc_cls.acquire, proc_cls.net_span, net_cls._flush, net_cls._client_publish)
    state = {"pub": False}

    def flush(self: Any, key: tuple[int, int]) -> None:
        if key[0] != self.server:
            flushes.append((key[0], self.k.now, self._bundler.records(key)))
        saved[2](self, key)

    def client_publish(self: Any, m: Any) -> None:
        state["pub"] = True
        try:
            saved[3](self, m)
        finally:
            state["pub"] = False

    def net_span(self: Any, a: float, gil: bool) -> tuple[float, float]:
        s, end = saved[1](self, a, gil)
        if self.name == host:
            bw.net_starts[end] = s
        return s, end

    def acquire(self: Any, a: float, length: float, wait: float = 0.0) -> tuple[float, int]:
        s, c = saved[0](self, a, length, wait)
        if self.name == host and state["pub"] and lo <= a < hi:
            r = a if a > self.free else self.free
            nf = self.net_free
            lock = min(nf, r + self.switch) - r if self.switch > 0.0 and nf > r else 0.0
            bw.bursts += 1
            bw.run += length
            bw.lock += lock
            if lock > 0.0:
                bw.lock_unstarted += max(0.0, min(bw.net_starts.get(nf, r), r + lock) - r)
            bw.runq += wait
            bw.core += s - (r + lock + wait)
        return s, c

    proc_cls.acquire, proc_cls.net_span = acquire, net_span  # type: ignore[method-assign]
    net_cls._flush, net_cls._client_publish = flush, client_publish  # type: ignore[method-assign]
    try:
        yield flushes, bw
    finally:
        for cls, name, fn in zip((proc_cls, proc_cls, net_cls, net_cls),
                                 ("acquire", "net_span", "_flush", "_client_publish"), saved,
                                 strict=True):
            setattr(cls, name, fn)


def des_turns(sc: Scenario, method: str, host: str = "host0"
              ) -> tuple[dict[int, list[tuple[float, int]]], BurstWait, dict[str, Any]]:
    """One DES run of ``method`` (per message): each host client's turns ``(flush
    time, records)`` in the metrics window, the publish bursts of process ``host``
    (:class:`BurstWait`) and the run's figures."""
    from sigma_des.calibrate.target import des_figures

    with _instrumented(host, sc.warmup, sc.duration) as (flushes, bw):
        figs = des_figures(sc, method)
    turns: dict[int, list[tuple[float, int]]] = {}
    for c, t, k in flushes:
        if sc.warmup <= t < sc.duration:
            turns.setdefault(c, []).append((t, k))
    bw.net_starts = {}
    return turns, bw, figs


def compare_rows(campaign: Path, cell: str, methods: tuple[str, ...]) -> list[dict[str, Any]]:
    """Live (each kept copy of ``cell`` in ``campaign/live/``) and DES (the campaign's
    calibration prepared for the cell, as the suite predicts it) rows of
    :func:`turn_stats`, with the live completions' lateness (µs, median and mean) and
    the DES host0 publish bursts' thread time per burst (µs: run, lock and its part
    before the network thread's burst started, run queue, core)."""
    from sigma_lab.studies.validation.grid import Cell, full_plan
    from sigma_lab.studies.validation.runs import des_scenario, load_calibration

    cal, rep = load_calibration(campaign / "cal")
    nodes = int(cell.split("-")[0][1:])
    sc = des_scenario(cal, rep, Cell(cell, nodes, "bundle"), full_plan(methods),
                      campaign / "cells" / "samples")
    lo, hi = sc.warmup, sc.duration
    rows: list[dict[str, Any]] = []
    for run in sorted((campaign / "live").glob(f"{cell}*")):
        if run.name != cell and not run.name.startswith(f"{cell}-c"):
            continue
        msgs = pd.read_csv(run / "messages.csv.gz")
        for m in methods:
            late = live_lateness(msgs, m, lo, hi, sc.cores_per_host) * 1e6
            rows.append({"source": f"live {run.name}", "method": m,
                         **turn_stats(live_turns(msgs, m, lo, hi), hi - lo),
                         "late_us_median": float(np.median(late)) if late.size else np.nan,
                         "late_us_mean": float(late.mean()) if late.size else np.nan})
    for m in methods:
        turns, bw, _figs = des_turns(sc, m)
        b = max(bw.bursts, 1)
        rows.append({"source": f"DES {cell}", "method": m, **turn_stats(turns, hi - lo),
                     **{f"{k}_us": getattr(bw, k) / b * 1e6
                        for k in ("run", "lock", "lock_unstarted", "runq", "core")}})
    return rows
