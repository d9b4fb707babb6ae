"""The deployment of a live run: ``[deployment]`` and the broker's services, fitted.

``sigma-des live`` runs the broker, the alignment server and every host process on
this one machine, so the calibrated scenario gets ``deployment.preset = "colocated"``
and, from the live run's ``summary.json`` (``live.<method>``) and ``cpu.csv``:
``cores`` (the CPUs the runner could use), ``background`` (other processes' CPU in the
metrics windows, at most :data:`BACKGROUND_CAP` × ``cores``; warned about on a
saturated machine), each process kind's CPU per message and per wake-up by the
Utilization Law on its busy CPU (one thread, or with the thread columns two threads in
tandem: ``*_demand``, ``*_wake``, ``*_wake_side``, ``*_net_msg``, ``*_net_wake``), the
measured run-queue waits (``*_runq``; the hosts' kept constant unless ``growth``, the
broker's and the server's growing with their machine's load), the record cost of a bundle
(``*_record``, the loop line's slope), the broker's busy CPU per message in or out as
both of its service times, ``lock_switch`` = the server loop's measured
hand-over interval (:func:`hand_over`), ``server_tick = 0``, ``clients = "host"`` and
``bundle`` as run. Without a ``cpu.csv`` nothing is fitted (no CPU stage; a warning
says so). Each rule, its formula and why it is so: docs/concepts/live-and-calibration.md
("The machine") and docs/concepts/decisions.md.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.calibrate.demands import fit_demands, kind_rows, read_cpu
from sigma_des.live.cpu import CPU_FILE, RUNQ_COLUMN, THREAD_COLUMNS, WAKE_COLUMNS, WALL_COLUMN
from sigma_des.live.loop import WakeStats
from sigma_des.net.cpu import queue_wait
from sigma_des.net.spec import DeploymentSpec

__all__ = ["BACKGROUND_CAP", "GROWING", "LIVE_LOCK_SWITCH", "SATURATED", "CpuFit", "fit_deployment",
           "hand_over", "live_info", "path_services", "pooled_demand", "recorded"]

#: Largest ``background`` a calibration writes, as a share of ``cores``.
BACKGROUND_CAP = 0.95
#: Longest ``deployment.lock_switch``: Python's interpreter-lock switch interval, which
#: the live processes do not change (``sys.getswitchinterval()``'s default): a busy
#: thread gives the lock up at the latest then. Also the value for a run whose
#: ``cpu.csv`` cannot show the hand-over (:func:`hand_over`).
LIVE_LOCK_SWITCH = 0.005
#: A machine this busy (share of its cores, ours + background) is warned about.
SATURATED = 0.95
#: Process kinds whose run-queue wait a calibration lets grow with the machine's load
#: (the floor is the measured wait less the queue at the run's utilisation): live's
#: broker and server wait as the machine's queue does, the hosts far less.
GROWING = ("broker", "server")


@dataclass(frozen=True)
class CpuFit:
    """What :func:`fit_deployment` fitted.

    Attributes:
        deployment: the ``[deployment]`` table.
        broker_service: the broker's demand per inbound PUBLISH and per delivery (s).
        report: the fitted figures and what they came from.
        wake_share: per kind (``host``, ``server``), the live loops' wake-ups per call:
            the share of bursts :func:`path_services` charges the wake-up cost.
    """

    deployment: DeploymentSpec
    broker_service: float
    report: dict[str, Any]
    wake_share: dict[str, float] = field(default_factory=dict)


def pooled_demand(table: pd.DataFrame, kind: str) -> tuple[float, float, float]:
    """``(Σ busy / Σ messages, Σ busy, Σ messages)`` over the rows of ``kind``
    (``server``, ``broker``, or ``host`` for every ``host<H>``) with a measured demand."""
    rows = kind_rows(table, kind)
    rows = rows.loc[np.isfinite(rows["demand_s"].to_numpy(dtype=np.float64))]
    busy, msgs = float(rows["busy_s"].sum()), float(rows["messages"].sum())
    return (busy / msgs if msgs > 0 else math.nan), busy, msgs


def live_info(source: Path) -> dict[str, dict[str, Any]]:
    """``summary.json``'s ``live`` table per method (empty if absent)."""
    summ = (source if source.is_dir() else source.parent) / "summary.json"
    if not summ.exists():
        return {}
    live = json.loads(summ.read_text(encoding="utf-8")).get("live", {})
    return {str(m): v for m, v in live.items() if isinstance(v, dict)}


def recorded(info: dict[str, dict[str, Any]], key: str, default: Any, what: str,
             warn: list[str]) -> Any:
    """The value of ``key`` the live run recorded (``info``: :func:`live_info`), or
    ``default`` with a warning saying ``what`` was taken instead."""
    vals = [v[key] for v in info.values() if key in v]
    if not vals:
        warn.append(f"the live run's summary.json does not record {key!r}: {what}")
        return default
    return vals[0]


def _background(cpu: pd.DataFrame, cores: int, warn: list[str]) -> tuple[float, float, float]:
    """Pooled background cores (capped), the measured value and the machine's busy cores
    (ours + background) over the metrics windows."""
    bg = cpu[cpu["process"] == "background"]
    win = float(bg["window_s"].sum())
    measured = float(bg["cpu_s"].sum()) / win if win > 0 else 0.0
    ours = cpu[(cpu["process"] != "background") & cpu["cpu_s"].map(math.isfinite)]
    busy = measured + (float(ours["cpu_s"].sum()) / win if win > 0 else 0.0)
    cap = BACKGROUND_CAP * cores
    if measured > cap:
        warn.append(f"background CPU {measured:.3f} cores clamped to {cap:g} "
                    f"({BACKGROUND_CAP:g} of {cores} cores): the machine had no capacity left")
    if busy >= SATURATED * cores:
        warn.append(f"the machine was saturated during the run ({busy:.2f} of {cores} cores "
                    "busy): the background then is cores minus what our processes got, so the "
                    "DES's CPU runs at utilization ~1 by construction; calibrate on a "
                    "quieter machine")
    return min(max(measured, 0.0), cap), measured, busy


def _wake(cpu: pd.DataFrame, table: pd.DataFrame, kind: str,
          warn: list[str]) -> tuple[float, float, dict[str, float]]:
    """``(wake, demand, report)`` of one process kind (see the module doc); ``wake`` 0
    when the wake-up columns are missing or give no positive cost."""
    d, busy, msgs = pooled_demand(table, kind)
    rows = kind_rows(cpu, kind)
    cols = [c for c in WAKE_COLUMNS if c in rows.columns]
    ok = (rows[cols].map(math.isfinite).all(axis=1) if len(cols) == len(WAKE_COLUMNS)
          else pd.Series(False, index=rows.index))
    if not ok.any():
        warn.append(f"no {kind} loop wake-ups recorded (a live run before them?): "
                    f"deployment.{kind}_wake 0, the whole CPU per message")
        return 0.0, _demand(d, busy, msgs, kind, warn), {}
    w = WakeStats.pooled([{"wakes": int(r.wakes), "calls": int(r.calls),
                           "cpu_s": r.loop_cpu_s, "skk": r.skk, "skc": r.skc,
                           "wall_s": getattr(r, WALL_COLUMN, math.nan)}
                          for r in rows.loc[ok].itertuples(index=False)])
    a, b = w.line()
    rep = {f"{kind}_wakes": float(w.wakes), f"{kind}_calls": float(w.calls),
           f"{kind}_loop_cpu_s": w.cpu_s, f"{kind}_loop_wake_s": a, f"{kind}_loop_call_s": b}
    if RUNQ_COLUMN in rows.columns and rows[RUNQ_COLUMN].map(math.isfinite).all():
        # measured, reported; the DES's own wait for a core is its CPU stage's
        rep[f"{kind}_runq_wait_per_msg_s"] = float(rows[RUNQ_COLUMN].sum()) / msgs
    if math.isfinite(w.wall_s):  # measured, reported; not (yet) a model parameter
        rep[f"{kind}_loop_wall_s"] = w.wall_s
        rep[f"{kind}_loop_stalled_per_wake_s"] = (w.wall_s - w.cpu_s) / w.wakes
    if not (math.isfinite(a) and a > 0 and w.cpu_s > 0 and math.isfinite(busy) and busy > 0):
        warn.append(f"{kind} loop: no positive per-wake-up CPU (line {a * 1e6:.3g} µs + "
                    f"{b * 1e6:.3g} µs a call over {w.wakes} wake-ups): deployment."
                    f"{kind}_wake 0, the whole CPU per message")
        return 0.0, _demand(d, busy, msgs, kind, warn), rep
    # each message costs one call in each of the process's two threads (the loop's
    # slope b, and as much in paho's network thread); the rest is per wake-up
    per_msg = 2.0 * b if b > 0 else math.nan
    wake = (busy - per_msg * msgs) / w.wakes if msgs > 0 else math.nan
    if not (math.isfinite(per_msg) and math.isfinite(wake) and wake > 0):
        warn.append(f"{kind}: no positive per-wake-up CPU left after 2 x {b * 1e6:.3g} µs a "
                    f"message ({busy:.3f} CPU s, {msgs:.0f} messages, {w.wakes} wake-ups): "
                    f"deployment.{kind}_wake 0, the whole CPU per message")
        return 0.0, _demand(d, busy, msgs, kind, warn), rep
    rep[f"{kind}_wake_share"] = w.wakes / w.calls
    return wake, per_msg, rep


def _threads(cpu: pd.DataFrame, table: pd.DataFrame, rep: dict[str, float], kind: str,
             warn: list[str]) -> dict[str, float] | None:
    """The kind's two threads (module doc, *network thread*): ``{"demand", "wake",
    "net_msg", "net_wake", "side"}``, or None (said in a warning) without the thread
    columns or without a positive cost per wake-up left in either thread.

    The process's busy CPU is split between its threads as their measured CPU is
    (``main_cpu_s``, ``net_cpu_s``); each thread's message costs one call, the loop
    line's slope ``b`` (one run cannot tell a thread's per-message from its per-wake-up
    CPU: every method sends as many messages), and the Utilization Law gives the rest
    per wake-up: the loop thread's over its loop wake-ups, the network thread's over its
    voluntary context switches (a return from its ``select``, or from a wait for the
    interpreter lock). ``side`` (the part beside the thread per network wake-up) starts
    at the network thread's wake-up; the hop match scales it until the DES's CPU is the
    live run's (the DES's network thread wakes less often than live's switches)."""
    _d, busy, msgs = pooled_demand(table, kind)
    rows = kind_rows(cpu, kind)
    cols = list(THREAD_COLUMNS[:4])
    b, wakes = rep.get(f"{kind}_loop_call_s", math.nan), rep.get(f"{kind}_wakes", 0.0)
    if not (set(cols) <= set(rows.columns) and len(rows)
            and rows[cols].map(math.isfinite).all().all()):
        warn.append(f"no {kind} thread columns recorded (a live run before them?): paho's "
                    f"thread is a wake-up's part beside the loop (deployment.{kind}_wake_side)")
        return None
    main, net = float(rows["main_cpu_s"].sum()), float(rows["net_cpu_s"].sum())
    switches = float(rows["net_switches"].sum())
    ok = main > 0 and net > 0 and switches > 0 and wakes > 0 and b > 0 and msgs > 0
    net_busy = busy * net / (main + net) if ok else math.nan
    net_wake = (net_busy - b * msgs) / switches if ok else math.nan
    loop_wake = (busy - net_busy - b * msgs) / wakes if ok else math.nan
    if not (net_wake > 0 and loop_wake > 0):
        warn.append(f"{kind}: no positive per-wake-up CPU in both threads (loop "
                    f"{loop_wake * 1e6:.3g} µs, network {net_wake * 1e6:.3g} µs after "
                    f"{b * 1e6:.3g} µs a message): paho's thread is a wake-up's part beside "
                    f"the loop (deployment.{kind}_wake_side)")
        return None
    rep[f"{kind}_net_cpu_share"] = net / (main + net)
    rep[f"{kind}_net_switch_share"] = switches / msgs
    return {"demand": b, "wake": loop_wake, "net_msg": b, "net_wake": net_wake,
            "side": net_wake}


def _kind_fit(cpu: pd.DataFrame, table: pd.DataFrame, kind: str, threads: bool,
              warn: list[str]) -> dict[str, Any]:
    """One kind's (``host``, ``server``) ``demand``, ``wake``, ``wake_side``, ``net_msg``,
    ``net_wake`` and its ``rep``: one thread (:func:`_wake`, :func:`_split_wake`), or
    with ``threads`` and the thread columns two (:func:`_threads`)."""
    wake, demand, rep = _wake(cpu, table, kind, warn)
    wake, side = _split_wake(wake, rep, kind)
    out: dict[str, Any] = {"demand": demand, "wake": wake, "wake_side": side, "net_msg": 0.0,
                           "net_wake": 0.0, "rep": rep}
    if threads and side > 0.0 and (t := _threads(cpu, table, rep, kind, warn)):
        out.update(demand=t["demand"], wake=t["wake"], wake_side=t["side"],
                   net_msg=t["net_msg"], net_wake=t["net_wake"])
    return out


def _split_wake(wake: float, rep: dict[str, float], kind: str) -> tuple[float, float]:
    """``(deployment.<kind>_wake, <kind>_wake_side)``: of a wake-up's CPU, the loop
    thread's own (the loop line's intercept ``a``) holds the process's thread, the rest
    (paho's network thread, and whatever else runs per wake-up) runs beside it; the
    whole ``wake`` on the thread when the line gives no ``a`` in ``(0, wake)``."""
    a = rep.get(f"{kind}_loop_wake_s", math.nan)
    if not (math.isfinite(a) and 0.0 < a < wake):
        return wake, 0.0
    return a, wake - a


def hand_over(cpu: pd.DataFrame) -> float:
    """The server's loop thread's busy wall seconds per voluntary switch beyond its
    wake-ups, ``Σ loop_wall_s / (Σ main_switches - Σ wakes)`` over its rows (every
    method): how long the busy thread runs, on average, before another thread (paho's
    network thread) gets the interpreter lock from it. A busy live loop gives the lock
    up at every blocking call (a publish's socket write, a log line), not only at
    Python's switch interval; a wake-up's own end is one switch each, so those are
    taken out. At most :data:`LIVE_LOCK_SWITCH`; NaN where the columns are missing
    (a run recorded before them) or no such switch happened.
    """
    rows = kind_rows(cpu, "server")
    need = [WALL_COLUMN, "main_switches", "wakes"]
    if not len(rows) or any(c not in rows.columns for c in need):
        return math.nan
    r = rows[need].dropna()
    extra = float(r["main_switches"].sum() - r["wakes"].sum())
    wall = float(r[WALL_COLUMN].sum())
    if not (extra > 0.0 and wall > 0.0):
        return math.nan
    return min(wall / extra, LIVE_LOCK_SWITCH)


def _lock_switch(cpu: pd.DataFrame, warn: list[str]) -> tuple[float, float]:
    """``deployment.lock_switch`` and the measured hand-over (:func:`hand_over`; NaN:
    not measured, then Python's switch interval, warned)."""
    switch = hand_over(cpu)
    if math.isfinite(switch):
        return switch, switch
    warn.append(f"{CPU_FILE} does not show the server loop's hand-overs (loop wall "
                "time and switch counts; a run of an older version?): lock_switch = "
                f"{LIVE_LOCK_SWITCH * 1e3:g} ms, Python's switch interval, taken")
    return LIVE_LOCK_SWITCH, switch


def _runq_floor(cpu: pd.DataFrame, kind: str, u: float, cores: int,
                warn: list[str], growth: bool) -> tuple[float, float]:
    """``(deployment.<kind>_runq, measured wait per CPU second)``: the run-queue wait of
    the kind's processes per CPU second they used; with ``growth``, less what the
    machine's queue gives at its utilisation ``u`` (:func:`queue_wait`), at least 0;
    ``(0, NaN)`` unmeasured."""
    rows = kind_rows(cpu, kind)
    ok = RUNQ_COLUMN in rows.columns and len(rows) > 0
    if not ok or not rows[RUNQ_COLUMN].map(math.isfinite).all():
        warn.append(f"no {kind} run-queue wait recorded (a live run before it?): "
                    f"deployment.{kind}_runq 0")
        return 0.0, math.nan
    busy = float(rows["cpu_s"].sum())
    q = float(rows[RUNQ_COLUMN].sum()) / busy if busy > 0 else 0.0
    return (max(q - queue_wait(cores, u), 0.0) if growth else q), q


def _runq_keys(runq: dict[str, tuple[float, float]], growth: bool) -> dict[str, Any]:
    """The ``[deployment]`` run-queue keys from each kind's ``(floor, measured)``: the
    broker's and the server's waits grow with load in any case (:data:`GROWING`), every
    kind's with ``growth``; nothing grows where nothing was measured."""
    measured = {k: math.isfinite(q) for k, (_f, q) in runq.items()}
    return {"host_runq": runq["host"][0], "server_runq": runq["server"][0],
            "broker_runq": runq["broker"][0],
            "runq_growth": growth and any(measured.values()),
            **{f"{k}_runq_growth": not growth and measured[k] for k in GROWING}}


def _record(rep: dict[str, float], kind: str, demand: float) -> float:
    """``deployment.<kind>_record``: the loop line's slope per call, in ``[0, demand]``
    (0 without a line: a run recorded before the wake-up columns)."""
    b = rep.get(f"{kind}_loop_call_s", math.nan)
    return float(min(max(b, 0.0), demand)) if math.isfinite(b) else 0.0


def _demand(d: float, busy: float, msgs: float, kind: str, warn: list[str]) -> float:
    if not math.isfinite(d):
        warn.append(f"no {kind} CPU demand could be measured: deployment.{kind}_demand 0")
        return 0.0
    if d < 0:
        warn.append(f"{kind} CPU demand {d * 1e6:.1f} µs < 0 ({busy:.3f} s busy over "
                    f"{msgs:.0f} messages) set to 0")
        return 0.0
    return d


def fit_deployment(source: Path, base_broker: float, warn: list[str], threads: bool = True,
                   growth: bool = False) -> CpuFit | None:
    """The colocated deployment of the live run at ``source`` (see the module doc).

    Args:
        source: the live ``--out`` directory (its ``cpu.csv`` and ``summary.json``).
        base_broker: the base scenario's broker service, kept if the broker was not
            measured (an external broker).
        warn: warnings are appended here.
        threads: fit the two threads apart where ``cpu.csv`` has them (False: one
            thread, the network thread's CPU a wake-up's part beside it).
        growth: run-queue waits that grow with the machine's load (Erlang C; floors
            net of it) instead of the measured waits kept constant.

    Returns:
        The fit, or None without a ``cpu.csv`` (no CPU stage).
    """
    cpu = read_cpu(source)
    if cpu is None:
        warn.append(f"no {CPU_FILE} next to the source: no CPU stage fitted "
                    "(deployment.preset 'none')")
        return None
    table, bg_per_method, w = fit_demands(cpu)
    warn.extend(w)
    info = live_info(source)
    here = len(os.sched_getaffinity(0))
    cores = int(recorded(info, "cores", here, f"this machine's {here} CPUs taken", warn))
    bundle = bool(recorded(info, "bundle", False, "bundle = false taken", warn))
    if bundle:
        warn.append("the live run bundled states (--bundle): its demands are per PUBLISH, "
                    "a bundle of a loop turn's states; the DES bundles the states published "
                    "while a host's process is busy, so its bundles are as large as its "
                    "host demand makes them (docs/concepts/deployment.md, 'Bundles')")
    background, measured, busy = _background(cpu, cores, warn)
    k = {kind: _kind_fit(cpu, table, kind, threads, warn) for kind in ("host", "server")}
    host_rep, server_rep = k["host"]["rep"], k["server"]["rep"]
    host, server = k["host"]["demand"], k["server"]["demand"]
    broker, b_busy, b_msgs = pooled_demand(table, "broker")
    if not math.isfinite(broker) or broker < 0:
        warn.append("the broker's CPU was not measured (an external broker?): its "
                    f"services kept from the base scenario ({base_broker * 1e6:.3g} µs)")
        broker = base_broker
    host_rec = _record(host_rep, "host", host)
    server_rec = _record(server_rep, "server", server)
    u = busy / cores
    lock, switch = _lock_switch(cpu, warn)
    runq = {kind: _runq_floor(cpu, kind, u, cores, warn, growth or kind in GROWING)
            for kind in ("host", "server", "broker")}
    dep = DeploymentSpec(preset="colocated", cores=cores, background=background,
                         host_demand=host, server_demand=server, server_tick=0.0,
                         host_wake=k["host"]["wake"], server_wake=k["server"]["wake"],
                         host_record=host_rec, server_record=server_rec,
                         lock_switch=lock, **_runq_keys(runq, growth),
                         **{f"{kind}_{key}": k[kind][key] for kind in k
                            for key in ("wake_side", "net_msg", "net_wake")},
                         clients="host", bundle=bundle)
    report = {
        "deployment_cores": cores, "deployment_background_cores": background,
        "background_cores_measured": measured, "machine_busy_cores": busy,
        **{f"{kind}_{key}_s": k[kind][key] for kind in k
           for key in ("demand", "wake", "wake_side", "net_msg", "net_wake")},
        "broker_demand_s": broker,
        "host_record_s": host_rec, "server_record_s": server_rec,
        "machine_utilisation": u, "lock_switch_measured_s": switch,
        **{f"{k}_runq_per_cpu_s": q for k, (_f, q) in runq.items()},
        **{f"{k}_runq_floor": f for k, (f, _q) in runq.items()},
        **host_rep, **server_rep,
        "broker_messages": b_msgs, "broker_busy_s": b_busy,
        "background_cores": bg_per_method, "cpu_demands": table.to_dict("records"),
        "live_load1": {m: v.get("load1") for m, v in info.items()},
    }
    share = {k: r[f"{k}_wake_share"] for k, r in (("host", host_rep), ("server", server_rep))
             if f"{k}_wake_share" in r}
    share.update({f"{k}_net": r[f"{k}_net_switch_share"]
                  for k, r in (("host", host_rep), ("server", server_rep))
                  if f"{k}_net_switch_share" in r})
    return CpuFit(dep, broker, report, share)


def path_services(dep: DeploymentSpec, publish: float, delivery: float,
                  wake_share: dict[str, float] | None = None, u: float = 0.0
                  ) -> dict[str, float]:
    """CPU service the DES spends on one message's measured path, per direction (s).

    The latency ends at the receiving client's receipt (where live stamps it, before
    the receiver's burst; docs/concepts/deployment.md), so a path holds the sender's
    publish burst and the broker's two services: ``up`` (a state: the host's burst) and
    ``down`` (a trigger: the server's), every burst slowed by the background
    (``cores / (cores - background)``). A sender's burst holds its wake-up cost when its
    thread was idle: on average ``wake_share`` (the live loops' wake-ups per call) of
    it. Without a CPU stage only the broker's services, unscaled.

    With run-queue waits (``*_runq``, ``runq_growth``, ``*_runq_growth``) the
    broker's services and the receiver's burst (a state's: the server's; a trigger's: a
    host's) wait ``q`` per CPU second of them, ``q = floor + queue_wait(cores, u)`` at
    the calibration run's machine utilisation ``u`` for a kind that grows (the floor
    alone for one that does not): the receipt is stamped after the receiver's wait.

    Also ``recv_up`` and ``recv_down``: the receiver's burst for a message that waited
    for its thread (the server's demand for a state, a host's for a trigger; no
    wake-up, the thread was busy). A receipt within that (and the hold tolerance) of
    the previous one at the receiver may have waited for the thread, which the DES
    adds itself (the latency ends when the process takes the message).
    """
    if not dep.cpu:
        return {"up": publish + delivery, "down": publish + delivery, "recv_up": 0.0,
                "recv_down": 0.0, "send_up": 0.0}
    share = wake_share or {}
    scale = dep.cores / (dep.cores - dep.background)
    broker = (publish + delivery) * scale
    # a wake-up's part beside the thread (*_wake_side) is on no message's path
    host = dep.host_demand + dep.host_wake * share.get("host", 0.0)
    server = dep.server_demand + dep.server_wake * share.get("server", 0.0)
    # the broker's and the receiver's run-queue waits are in a measured latency (all 0,
    # and the sums exactly the plain ones, without them)
    g = queue_wait(dep.cores, u)
    q_b, q_h, q_s = (getattr(dep, f"{k}_runq") + (g if dep.grows(k) else 0.0)
                     for k in ("broker", "host", "server"))
    # with a network thread: the sender's write is on the path, and the receipt is
    # stamped at the end of the receiver's network-thread burst (its wait included)
    h_net = dep.host_net_msg + dep.host_net_wake * share.get("host_net", 0.0)
    s_net = dep.server_net_msg + dep.server_net_wake * share.get("server_net", 0.0)
    recv_s = (1 + q_s) * s_net if s_net > 0 else q_s * server
    recv_h = (1 + q_h) * h_net if h_net > 0 else q_h * host
    return {"up": broker * (1 + q_b) + (host + h_net + recv_s) * scale,
            "down": broker * (1 + q_b) + (server + s_net + recv_h) * scale,
            "recv_up": (dep.server_net_msg if s_net > 0 else dep.server_demand) * scale,
            "recv_down": (dep.host_net_msg if h_net > 0 else dep.host_demand) * scale,
            "send_up": dep.host_demand * scale}
