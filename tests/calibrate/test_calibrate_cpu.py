"""`calibrate` feeds the CPU stage: the deployment from a synthetic ``cpu.csv`` and
``summary.json`` (hand-computed), the Utilization Law pooled exactly, the hop latencies
net of the path's CPU services, and ``compute.host_share`` by the intraclass correlation."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.special import ndtri

from sigma_des import load
from sigma_des.calibrate.demands import fit_demands
from sigma_des.calibrate.fit import calibrate, calibrated_toml, for_target
from sigma_des.calibrate.fit_cpu import hand_over, path_services, pooled_demand
from sigma_des.calibrate.fit_step import HOST_SHARE_CAP, host_share, icc
from sigma_des.cli import main
from sigma_des.live.cpu import write_cpu
from sigma_des.net.cpu import queue_wait
from sigma_des.net.spec import DeploymentSpec
from tests.calibrate.test_calibrate_inputs import SETS, STATE_LAT, TRIG_LAT, _run, _write

WINDOW, IDLE = 4.0, 1.0
#: process -> (idle CPU rate, messages, busy CPU seconds in the window)
PROCS = {"server": (0.01, 5000, 0.4), "host0": (0.0, 2000, 0.3),
         "host1": (0.02, 2500, 0.5), "broker": (0.005, 9000, 0.09)}
BACKGROUND_CPU = 1.2  # CPU seconds other processes took in the window: 0.3 cores
CORES = 4


def _cpu_rows(procs: dict[str, tuple[float, int, float]], bg: float) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    for pid, (name, (idle, msgs, busy)) in enumerate(procs.items()):
        rows.append({"process": name, "pid": pid, "idle_s": IDLE, "idle_cpu_s": idle * IDLE,
                     "window_s": WINDOW, "cpu_s": idle * WINDOW + busy, "messages": msgs})
    rows.append({"process": "background", "pid": -1, "idle_s": IDLE, "idle_cpu_s": 0.1,
                 "window_s": WINDOW, "cpu_s": bg, "messages": math.nan})
    return rows


def _cpu_run(tmp: Path, live: dict[str, object] | None = None) -> Path:
    """The synthetic live run of test_calibrate_inputs with a cpu.csv and the live table."""
    sc = load(None, SETS)
    d = _write(tmp, sc, _run(sc))
    write_cpu({"bides": {"cpu": _cpu_rows(PROCS, BACKGROUND_CPU)}}, d)
    summ = json.loads((d / "summary.json").read_text())
    summ["live"] = {"bides": live if live is not None else
                    {"cores": CORES, "bundle": True, "load1": 0.5}}
    (d / "summary.json").write_text(json.dumps(summ))
    return d


def test_pooled_utilization_law_recovers_known_demands_exactly() -> None:
    """Two methods, two hosts: every host spends 150 µs per message whatever its idle
    rate and count, so the pooled demand Σ busy / Σ messages is 150 µs exactly."""
    rows = []
    for m, counts in (("none", (1000, 3000)), ("bides", (2000, 500))):
        procs = {f"host{h}": (0.01 * h, n, 150e-6 * n) for h, n in enumerate(counts)}
        procs["server"] = (0.0, 4000, 80e-6 * 4000)
        rows += [{"method": m, **r} for r in _cpu_rows(procs, 0.4)]
    table, _bg, warn = fit_demands(pd.DataFrame(rows))
    assert warn == []
    d, busy, msgs = pooled_demand(table, "host")
    assert msgs == 6500 and busy == pytest.approx(150e-6 * 6500, rel=1e-12)
    assert d == pytest.approx(150e-6, rel=1e-12)
    assert pooled_demand(table, "server")[0] == pytest.approx(80e-6, rel=1e-12)
    assert math.isnan(pooled_demand(table, "broker")[0])  # no broker row: no demand


def test_calibrate_writes_the_deployment_with_the_fitted_values(tmp_path: Path) -> None:
    sc, rep = calibrate(_cpu_run(tmp_path / "run"), tmp_path / "files")
    host = (0.3 + 0.5) / (2000 + 2500)  # 177.8 µs: pooled over both hosts
    server, broker = 0.4 / 5000, 0.09 / 9000  # 80 µs, 10 µs
    want = DeploymentSpec(preset="colocated", cores=CORES, background=BACKGROUND_CPU / WINDOW,
                          host_demand=host, server_demand=server, server_tick=0.0,
                          clients="host", bundle=True)
    dep = sc.deployment
    for key in ("preset", "cores", "clients", "bundle", "server_tick"):
        assert getattr(dep, key) == getattr(want, key), key
    for key in ("background", "host_demand", "server_demand"):
        assert getattr(dep, key) == pytest.approx(getattr(want, key), rel=1e-12), key
    # this cpu.csv cannot show the server loop's hand-overs: Python's switch interval
    assert dep.lock_switch == 0.005 == sys.getswitchinterval()
    for svc in (sc.broker.publish_service, sc.broker.delivery_service):
        assert svc.dist == "constant" and svc.value == pytest.approx(broker, rel=1e-12)
    # written out and read back: the same keys and values
    path = tmp_path / "cal.toml"
    path.write_text(calibrated_toml(sc, rep))
    back = load(str(path))
    assert back.deployment == sc.deployment and back.broker == sc.broker
    assert back.compute.host_share == sc.compute.host_share
    text = path.read_text()
    assert '[deployment]\npreset = "colocated"' in text and 'clients = "host"' in text
    # the hop: the path latency less the CPU services the DES adds on it (the broker's
    # two and the sender's burst: the host's for a state, the server's for a trigger),
    # all slowed by 4 / (4 - 0.3)
    scale = CORES / (CORES - BACKGROUND_CPU / WINDOW)
    cpu_up = scale * (2 * broker + host)
    cpu_down = scale * (2 * broker + server)
    up = np.loadtxt(sc.net.host_link.latency.file)  # type: ignore[union-attr]
    down = np.loadtxt(sc.net.server_link.latency.file)  # type: ignore[union-attr]
    assert up.mean() == pytest.approx((STATE_LAT - cpu_up) / 2, rel=1e-8)  # %.9g files
    assert down.mean() == pytest.approx((np.mean(TRIG_LAT) - cpu_down) / 2, rel=1e-6)
    assert rep["path_cpu_service_up_s"] == pytest.approx(cpu_up, rel=1e-12)
    assert rep["path_cpu_service_down_s"] == pytest.approx(cpu_down, rel=1e-12)
    assert rep["server_queue_folded_into_server_link"] is False
    assert rep["state_held_frac"] == 0.0  # states 0.5 ms apart > 0.1 ms
    cpu_warnings = [w for w in rep["warnings"] if "cpu.csv" in w]
    assert cpu_warnings == ["cpu.csv does not show the server loop's hand-overs (loop wall "
                            "time and switch counts; a run of an older version?): "
                            "lock_switch = 5 ms, Python's switch interval, taken"]
    assert math.isnan(rep["lock_switch_measured_s"])


def _loop_rows(server: list[tuple[float, float, float]]) -> pd.DataFrame:
    """A cpu table with the server's (loop wall s, main switches, wakes) per method and
    a host whose loop wakes more often than it switches (timers due without a wait)."""
    rows = [{"method": f"m{i}", "process": "server", "loop_wall_s": w, "main_switches": sw,
             "wakes": wk} for i, (w, sw, wk) in enumerate(server)]
    rows.append({"method": "m0", "process": "host0", "loop_wall_s": 9.0,
                 "main_switches": 10.0, "wakes": 100.0})
    return pd.DataFrame(rows)


def test_the_hand_over_interval_is_the_busy_wall_time_per_switch_beyond_the_wake_ups() -> None:
    # pooled over methods: (0.3 + 0.1) s / ((3000 + 1000) - (2000 + 1000)) = 0.4 ms;
    # the host's rows are not the server's
    assert hand_over(_loop_rows([(0.3, 3000.0, 2000.0), (0.1, 1000.0, 1000.0)])) == \
        pytest.approx(0.4e-3, rel=1e-12)
    # a wake-up's own end is one switch each: no switch beyond them, nothing to measure
    assert math.isnan(hand_over(_loop_rows([(0.3, 2000.0, 2000.0)])))
    # a loop that kept the lock longer than Python's switch interval gave it up then
    assert hand_over(_loop_rows([(1.0, 110.0, 10.0)])) == 0.005  # 10 ms measured
    # a run recorded before the columns: nothing measured
    old = _loop_rows([(0.3, 3000.0, 2000.0)]).drop(columns=["loop_wall_s"])
    assert math.isnan(hand_over(old))


def test_a_campaign_takes_the_mean_hand_over_of_its_per_node_runs(tmp_path: Path) -> None:
    from sigma_des.calibrate.campaign import combine

    sc, rep = calibrate(_cpu_run(tmp_path / "run"), tmp_path / "files")
    fits = []
    for i, (sw, bundle) in enumerate(((0.0004, False), (0.0002, False), (0.001, True))):
        s = replace(sc, deployment=replace(sc.deployment, lock_switch=sw))
        fits.append((s, rep, {"name": f"r{i}", "bundle": bundle, "background": 0.0,
                              "figures": {}}))
    out, report, _primary = combine(fits, tmp_path / "combined")
    assert out.deployment.lock_switch == pytest.approx(0.0003, rel=1e-12)  # bundled left out
    assert report["lock_switch_s"] == out.deployment.lock_switch


def test_per_client_delivery_is_not_rescaled_with_one_client_per_host(tmp_path: Path) -> None:
    sc, rep = calibrate(_cpu_run(tmp_path / "run"), tmp_path / "files")
    tgt = for_target(sc, rep, ["nodes=40", "hosts=4"])
    assert tgt.broker.delivery_service.value == pytest.approx(0.09 / 9000, rel=1e-12)
    node_clients = for_target(sc, rep, ["nodes=40", "hosts=4", 'deployment.clients="node"',
                                        "deployment.bundle=false"])
    assert node_clients.broker.delivery_service.value == pytest.approx(
        0.09 / 9000 * 4 / 40, rel=1e-12)


def test_missing_live_table_and_saturation_are_said(tmp_path: Path) -> None:
    import os

    _sc, rep = calibrate(_cpu_run(tmp_path / "a", live={}), tmp_path / "fa")
    w = " | ".join(rep["warnings"])
    here = len(os.sched_getaffinity(0))
    assert f"does not record 'cores': this machine's {here} CPUs taken" in w
    assert "does not record 'bundle': bundle = false taken" in w
    assert _sc.deployment.cores == here and _sc.deployment.bundle is False
    # a machine busy with others: 3.9 of 4 cores' background is capped at 3.8
    d = _cpu_run(tmp_path / "b")
    write_cpu({"bides": {"cpu": _cpu_rows(PROCS, 3.9 * WINDOW)}}, d)
    sc, rep = calibrate(d, tmp_path / "fb")
    assert sc.deployment.background == pytest.approx(0.95 * CORES)
    w = " | ".join(rep["warnings"])
    assert "background CPU 3.900 cores clamped to 3.8" in w
    assert "the machine was saturated during the run" in w


def test_without_cpu_csv_no_cpu_stage_is_fitted(tmp_path: Path) -> None:
    sc0 = load(None, SETS)
    sc, rep = calibrate(_write(tmp_path / "run", sc0, _run(sc0)), tmp_path / "f")
    assert sc.deployment == DeploymentSpec()
    assert "no cpu.csv next to the source: no CPU stage fitted" in rep["warnings"][0]
    assert path_services(DeploymentSpec(), 1e-5, 2e-5) == {
        "up": 1e-5 + 2e-5, "down": 1e-5 + 2e-5, "recv_up": 0.0, "recv_down": 0.0,
        "send_up": 0.0}


def test_path_services_hold_the_senders_burst_not_the_receivers() -> None:
    """Background 1 of 4 cores: every service × 4/3. A state's path: the broker's two
    services and the host's publish burst; a trigger's: the broker's and the server's
    (the receiver's burst comes after the receipt, where the latency ends). A sender's
    burst holds its wake-up for the live share of calls that were wake-ups (host 0.4 of
    200 µs, server 0.25 of 400 µs). The receiver's burst (no wake-up: it waited) is the
    hold tolerance's addition."""
    dep = DeploymentSpec(preset="colocated", cores=4, background=1.0, host_demand=3e-4,
                         server_demand=6e-4, host_wake=2e-4, server_wake=4e-4)
    got = path_services(dep, 1.5e-5, 3e-5)
    assert got["up"] == pytest.approx((4.5e-5 + 3e-4) * 4 / 3, rel=1e-12)
    assert got["down"] == pytest.approx((4.5e-5 + 6e-4) * 4 / 3, rel=1e-12)
    got = path_services(dep, 1.5e-5, 3e-5, {"host": 0.4, "server": 0.25})
    assert got["up"] == pytest.approx((4.5e-5 + 3e-4 + 0.4 * 2e-4) * 4 / 3, rel=1e-12)
    assert got["down"] == pytest.approx((4.5e-5 + 6e-4 + 0.25 * 4e-4) * 4 / 3, rel=1e-12)
    assert got["recv_up"] == pytest.approx(6e-4 * 4 / 3, rel=1e-12)
    assert got["recv_down"] == pytest.approx(3e-4 * 4 / 3, rel=1e-12)
    # with run-queue waits the broker's and the receiver's waits are on the path too:
    # q = floor + queue_wait(4, u) at the run's utilisation u = 0.5
    rq = replace(dep, broker_runq=0.5, server_runq=0.25, host_runq=1.0, runq_growth=True)
    g = queue_wait(4, 0.5)
    got = path_services(rq, 1.5e-5, 3e-5, u=0.5)
    assert got["up"] == pytest.approx(
        4.5e-5 * 4 / 3 * (1.5 + g) + 3e-4 * 4 / 3 + (0.25 + g) * 6e-4 * 4 / 3, rel=1e-12)
    assert got["down"] == pytest.approx(
        4.5e-5 * 4 / 3 * (1.5 + g) + 6e-4 * 4 / 3 + (1.0 + g) * 3e-4 * 4 / 3, rel=1e-12)


def _wake_cols(a: float, b: float, wakes: list[int]) -> dict[str, float]:
    """Loop wake-up sums of wake-ups with the given call counts, each costing exactly
    ``a + b·k`` loop-thread CPU seconds."""
    return {"wakes": len(wakes), "calls": sum(wakes),
            "loop_cpu_s": sum(a + b * k for k in wakes), "skk": float(sum(k * k for k in wakes)),
            "skc": sum(k * (a + b * k) for k in wakes)}


def test_wake_up_and_per_message_demands_recovered_exactly(tmp_path: Path) -> None:
    """Each host's loop spends 50 µs per wake-up and 10 µs per call (wake-ups of 1, 2
    and 5 calls), the server's 80 and 20 µs; a process spends 2.5× its loop thread's
    CPU (paho's network thread too). Pooled over both hosts the line is exact, so
    ``host_wake = 50 µs`` and the per-message demand is the rest of the busy CPU
    over the messages: ``(busy − wake·W) / M``."""
    d = _cpu_run(tmp_path / "run")
    hosts = {"host0": _wake_cols(50e-6, 10e-6, [1, 2, 5] * 300),
             "host1": _wake_cols(50e-6, 10e-6, [1, 1, 2, 5] * 250),
             "server": _wake_cols(80e-6, 20e-6, [1, 3, 4] * 400)}
    procs = {"server": (0.01, 5000, 2.5 * hosts["server"]["loop_cpu_s"]),
             "host0": (0.0, 2000, 2.5 * hosts["host0"]["loop_cpu_s"]),
             "host1": (0.02, 2500, 2.5 * hosts["host1"]["loop_cpu_s"]),
             "broker": PROCS["broker"]}
    rows = _cpu_rows(procs, BACKGROUND_CPU)
    for r in rows:
        r.update(hosts.get(str(r["process"]), {}))
        # each loop's wake-ups took 1.5x their CPU in wall time; 0.1 s on a run queue
        r.update({"loop_wall_s": 1.5 * r.get("loop_cpu_s", math.nan), "runq_wait_s": 0.1})
    write_cpu({"bides": {"cpu": rows}}, d)
    sc, rep = calibrate(d, tmp_path / "files")
    dep = sc.deployment
    busy_h = procs["host0"][2] + procs["host1"][2]
    # reported, not fitted: the loop's time busy but not running, the run-queue wait
    loop_h = hosts["host0"]["loop_cpu_s"] + hosts["host1"]["loop_cpu_s"]
    assert rep["host_loop_stalled_per_wake_s"] == pytest.approx(
        0.5 * loop_h / (hosts["host0"]["wakes"] + hosts["host1"]["wakes"]), rel=1e-12)
    assert rep["server_runq_wait_per_msg_s"] == pytest.approx(0.1 / 5000, rel=1e-12)
    assert rep["host_runq_wait_per_msg_s"] == pytest.approx(0.2 / 4500, rel=1e-12)
    w_h = hosts["host0"]["wakes"] + hosts["host1"]["wakes"]
    # a message: one call in each thread (2 x 10 µs); the rest of the CPU per wake-up
    assert dep.host_demand == pytest.approx(20e-6, rel=1e-9)
    # of a wake-up's CPU, the loop line's intercept holds the thread, the rest runs
    # beside it (paho's thread)
    wake_h = (busy_h - 20e-6 * 4500) / w_h
    assert rep["host_loop_wake_s"] == pytest.approx(50e-6, rel=1e-9)
    assert dep.host_wake == rep["host_loop_wake_s"] == rep["host_wake_s"]
    assert dep.host_wake_side == pytest.approx(wake_h - 50e-6, rel=1e-9)
    assert dep.host_wake_side == rep["host_wake_side_s"] > 0.0
    assert dep.server_demand == pytest.approx(40e-6, rel=1e-9)
    wake_s = (procs["server"][2] - 40e-6 * 5000) / 1200
    assert dep.server_wake == pytest.approx(80e-6, rel=1e-9)
    assert dep.server_wake_side == pytest.approx(wake_s - 80e-6, rel=1e-9)
    assert rep["host_loop_call_s"] == pytest.approx(10e-6, rel=1e-9)
    # a further record of a bundle costs one call's worth (the line's slope)
    assert dep.host_record == pytest.approx(10e-6, rel=1e-9) == rep["host_record_s"]
    # run-queue waits: 0.1 s a process over its CPU; the hosts' kept as measured, the
    # broker's and the server's less the machine's queue at the run's utilisation (ours +
    # background over the 4 cores), which the DES adds back at its own load
    cpu_s = {k: procs[k][0] * WINDOW + procs[k][2] for k in procs}
    u = (BACKGROUND_CPU + sum(cpu_s.values())) / WINDOW / CORES
    assert rep["machine_utilisation"] == pytest.approx(u, rel=1e-12)
    q_h = 0.2 / (cpu_s["host0"] + cpu_s["host1"])
    assert rep["host_runq_per_cpu_s"] == pytest.approx(q_h, rel=1e-12)
    assert dep.host_runq == pytest.approx(q_h, rel=1e-12) and not dep.runq_growth
    g = queue_wait(CORES, u)
    assert 0.0 < g < 0.1 / cpu_s["broker"]
    assert dep.broker_runq == pytest.approx(0.1 / cpu_s["broker"] - g, rel=1e-12)
    assert dep.broker_runq_growth
    assert rep["broker_runq_per_cpu_s"] == pytest.approx(0.1 / cpu_s["broker"], rel=1e-12)
    assert 0.0 < g < 0.1 / cpu_s["server"]
    assert dep.server_runq == pytest.approx(0.1 / cpu_s["server"] - g, rel=1e-12)
    assert dep.server_runq_growth
    # --runq-growth: the floors less the machine's queue at the run's utilisation
    # (ours + background over the 4 cores), and the DES adds it back at its own load
    dep_g = calibrate(d, tmp_path / "files_g", runq_growth=True)[0].deployment
    assert dep_g.host_runq == pytest.approx(q_h - queue_wait(CORES, u), rel=1e-12)
    assert dep_g.host_runq > 0.0 and dep_g.runq_growth and not dep_g.broker_runq_growth
    assert not dep_g.server_runq_growth
    assert dep_g.server_runq == pytest.approx(dep.server_runq, rel=1e-12)
    assert dep_g.broker_runq == pytest.approx(dep.broker_runq, rel=1e-12)
    assert dep.server_record == pytest.approx(20e-6, rel=1e-9)
    assert rep["host_wake_share"] == pytest.approx(w_h / (900 * 8 / 3 + 250 * 9), rel=1e-12)
    # the sender's expected wake-up is on the path the hop samples are net of
    scale = CORES / (CORES - BACKGROUND_CPU / WINDOW)
    # ... and the broker's and the server's run-queue waits at the run's load (each
    # floor plus the queue: the measured wait)
    server = dep.server_demand + dep.server_wake * rep["server_wake_share"]
    assert rep["path_cpu_service_up_s"] == pytest.approx(
        scale * (2 * 0.09 / 9000 * (1 + 0.1 / cpu_s["broker"]) + dep.host_demand
                 + dep.host_wake * rep["host_wake_share"] + 0.1 / cpu_s["server"] * server),
        rel=1e-12)
    # without the wake-up columns (a run recorded before them): the whole CPU per message
    write_cpu({"bides": {"cpu": _cpu_rows(procs, BACKGROUND_CPU)}}, d)
    sc0, rep0 = calibrate(d, tmp_path / "files0")
    assert sc0.deployment.host_wake == 0.0 and sc0.deployment.host_record == 0.0
    assert sc0.deployment.host_demand == pytest.approx(busy_h / 4500, rel=1e-12)
    assert any("no host loop wake-ups recorded" in w for w in rep0["warnings"])
    # ... nor run-queue waits: no floors, no growth, said
    dep0 = sc0.deployment
    assert (dep0.host_runq, dep0.server_runq, dep0.broker_runq, dep0.runq_growth,
            dep0.broker_runq_growth, dep0.server_runq_growth) == (0.0, 0.0, 0.0, False,
                                                                   False, False)
    assert any("no broker run-queue wait recorded" in w for w in rep0["warnings"])


def test_runq_growth_is_a_calibrate_option(tmp_path: Path) -> None:
    """``sigma-des calibrate`` keeps the hosts' measured run-queue waits and lets the
    broker's and the server's grow; with ``--runq-growth`` the written scenario has every
    process's growth on and every floor net of Erlang C."""
    d = _cpu_run(tmp_path / "run")
    rows = _cpu_rows(PROCS, BACKGROUND_CPU)
    for r in rows:
        r["runq_wait_s"] = 0.1
    write_cpu({"bides": {"cpu": rows}}, d)
    out = {}
    for flag in ([], ["--runq-growth"]):
        path = tmp_path / f"c{len(flag)}" / "c.toml"
        path.parent.mkdir()
        assert main(["calibrate", str(d), "--out", str(path), "--no-check", "--no-match",
                     *flag]) == 0
        out[bool(flag)] = load(str(path)).deployment
    busy_h = sum(PROCS[h][0] * WINDOW + PROCS[h][2] for h in ("host0", "host1"))
    assert not out[False].runq_growth and out[True].runq_growth
    assert out[False].broker_runq_growth and not out[True].broker_runq_growth
    assert out[False].server_runq_growth and not out[True].server_runq_growth
    assert out[False].host_runq == pytest.approx(0.2 / busy_h, rel=1e-12)
    assert out[True].host_runq < out[False].host_runq
    assert out[True].broker_runq == pytest.approx(out[False].broker_runq, rel=1e-12)


def test_receipts_paced_by_the_servers_thread_count_as_held(tmp_path: Path) -> None:
    """The synthetic run's states reach the server 0.5 ms apart. With a server demand
    of 80 µs that is more than the tolerance plus its burst (none held); with 450 µs
    (× 4/3.7 background) a receipt 0.5 ms after the previous one may have waited for
    the server's thread: held (censored)."""
    _sc, rep = calibrate(_cpu_run(tmp_path / "a"), tmp_path / "fa")
    assert rep["state_held_frac"] == 0.0
    scale = CORES / (CORES - BACKGROUND_CPU / WINDOW)
    assert rep["hold_service_up_s"] == pytest.approx(0.4 / 5000 * scale, rel=1e-12)
    d = _cpu_run(tmp_path / "b")
    slow = {**PROCS, "server": (0.01, 5000, 450e-6 * 5000)}
    write_cpu({"bides": {"cpu": _cpu_rows(slow, BACKGROUND_CPU)}}, d)
    _sc, rep = calibrate(d, tmp_path / "fb")
    assert rep["hold_service_up_s"] == pytest.approx(450e-6 * scale, rel=1e-12)
    assert rep["state_held_frac"] > 0.4


def test_icc_hand_computed() -> None:
    """4 groups of 2: means 0, 1, 2, 3 ms, each ±0.5 ms. SSB = 2·Σ(m − 1.5)² = 10,
    MSB = 10/3; SSW = 8·0.25 = 2, MSW = 2/4 = 0.5; n0 = 2: ICC = (10/3 − 1/2)/(10/3 + 1/2)
    = 17/23 (ms², scale-free)."""
    x = [f + d for f in range(4) for d in (-0.5, 0.5)]
    g = [f for f in range(4) for _ in range(2)]
    assert icc(np.array(x) * 1e-3, g) == pytest.approx(17 / 23, rel=1e-12)
    assert icc([1.0, 1.0, 2.0, 2.0], [0, 0, 1, 1]) == pytest.approx(1.0)
    assert icc([1.0, 2.0, 1.0, 2.0], [0, 0, 1, 1]) == pytest.approx(-1.0)  # (0 - 0.5)/(0.5)
    assert math.isnan(icc([1.0, 2.0], [0, 1]))  # no group of two
    assert math.isnan(icc([1.0, 2.0], [0, 0]))  # one group


@pytest.mark.parametrize("rho", [0.0, 0.3, 0.8])
def test_host_share_recovers_a_known_copula_rho(rho: float) -> None:
    """Services drawn as the DES draws them (lognormal marginal, normal scores
    correlated ρ within a host and frame), 1500 frames x 2 hosts x 5 nodes: the ICC of
    the rank normal scores is ρ within 4 standard errors of the ICC (large-sample
    variance 2(1−ρ)²(1+(k−1)ρ)² / (k(k−1)(g−1)), k = 5, g = 3000: ±0.026 at ρ = 0.3)."""
    rng = np.random.default_rng(11)
    frames, hosts, k = 1500, 2, 5
    zh = rng.standard_normal((frames, hosts, 1))
    zn = rng.standard_normal((frames, hosts, k))
    z = math.sqrt(rho) * zh + math.sqrt(1 - rho) * zn
    cost = np.exp(-6.0 + 0.7 * z)  # any increasing marginal: the ranks are what count
    f, h, _ = np.meshgrid(range(frames), range(hosts), range(k), indexing="ij")
    pub = pd.DataFrame({"method": "bides", "frame": f.ravel(), "host": h.ravel(),
                        "cost": cost.ravel()})
    g = frames * hosts
    se = math.sqrt(2 * (1 - rho) ** 2 * (1 + (k - 1) * rho) ** 2 / (k * (k - 1) * (g - 1)))
    assert host_share(pub) == pytest.approx(rho, abs=4 * se)


def test_fitted_host_share_from_the_synthetic_run(tmp_path: Path) -> None:
    """The synthetic run's nodes publish 1, 1.5 ms (host 0) and 2, 2.5 ms (host 1) after
    every trigger: four score levels ±Φ⁻¹(1/8), ±Φ⁻¹(3/8) (mid-ranks of four equal
    quarters), groups {z1, z2} and {−z2, −z1}. With g groups of 2 (N = 2g):
    MSB = 2g·m²/(g−1) → 2m², MSW = 2g·h²/g = 2h² (m, h the mean and half-difference
    of z1, z2), n0 = 2: ICC = (m² − h²)/(m² + h²) = 0.515."""
    sc0 = load(None, SETS)
    sc, rep = calibrate(_write(tmp_path / "run", sc0, _run(sc0)), tmp_path / "f")
    z1, z2 = float(ndtri(1 / 8)), float(ndtri(3 / 8))
    m, h = (z1 + z2) / 2, (z2 - z1) / 2
    assert rep["step_time_host_share"] == pytest.approx((m * m - h * h) / (m * m + h * h),
                                                        abs=0.01)
    assert sc.compute.host_share == rep["step_time_host_share"] < HOST_SHARE_CAP


def test_the_two_threads_split_recovers_known_wake_ups_exactly(tmp_path: Path) -> None:
    """``cpu.csv`` with each process's threads apart: a host's loop spends 60 µs a
    wake-up and 10 µs a call (its line), its network thread 120 µs a voluntary switch
    and 10 µs a message; the server's 90 + 20 and 150 + 20 µs. The fit gives each
    thread's message one call (``b``) and the rest of that thread's CPU per its own
    wake-ups: ``*_net_msg = *_demand = b`` and the wake-ups exactly; the network
    thread's wake-up is also the starting value of the part the hop match scales to
    the live CPU (``*_wake_side``, placed beside the thread per network wake-up)."""
    d = _cpu_run(tmp_path / "run")
    cost = {"host0": (60e-6, 10e-6, 120e-6, [1, 2, 5] * 300, 900),
            "host1": (60e-6, 10e-6, 120e-6, [1, 1, 2, 5] * 250, 1100),
            "server": (90e-6, 20e-6, 150e-6, [1, 3, 4] * 400, 2000)}
    procs = dict(PROCS)
    extra: dict[str, dict[str, float]] = {}
    for name, (a, b, wn, calls, sw) in cost.items():
        msgs = PROCS[name][1]
        loop = a * len(calls) + b * msgs
        net = wn * sw + b * msgs
        procs[name] = (PROCS[name][0], msgs, loop + net)
        extra[name] = {**_wake_cols(a, b, calls), "main_cpu_s": loop, "main_switches": 1.0,
                       "net_cpu_s": net, "net_switches": float(sw), "net_threads": 1.0}
    rows = _cpu_rows(procs, BACKGROUND_CPU)
    for r in rows:
        r.update(extra.get(str(r["process"]), {}))
    write_cpu({"bides": {"cpu": rows}}, d)
    sc, rep = calibrate(d, tmp_path / "files")
    dep = sc.deployment
    assert dep.host_demand == dep.host_net_msg == pytest.approx(10e-6, rel=1e-9)
    assert dep.host_wake == pytest.approx(60e-6, rel=1e-9)
    assert dep.host_net_wake == pytest.approx(120e-6, rel=1e-9) == rep["host_net_wake_s"]
    assert dep.server_demand == dep.server_net_msg == pytest.approx(20e-6, rel=1e-9)
    assert dep.server_wake == pytest.approx(90e-6, rel=1e-9)
    assert dep.server_net_wake == pytest.approx(150e-6, rel=1e-9)
    assert dep.server_wake_side == dep.server_net_wake
    assert rep["server_net_switch_share"] == pytest.approx(2000 / 5000, rel=1e-12)
    # --one-thread: the same columns, one thread (the network thread's CPU beside it)
    sc1, _rep1 = calibrate(d, tmp_path / "files1", threads=False)
    assert sc1.deployment.server_net_wake == sc1.deployment.host_net_msg == 0.0
    assert sc1.deployment.server_demand == pytest.approx(40e-6, rel=1e-9)
    assert sc1.deployment.server_wake_side > 0.0
    # without the thread columns: the wake-up's part beside the loop, said
    write_cpu({"bides": {"cpu": [{k: v for k, v in r.items() if k not in extra["server"]
                                  or k in _wake_cols(1, 1, [1])} for r in rows]}}, d)
    sc0, rep0 = calibrate(d, tmp_path / "files0")
    assert sc0.deployment.server_net_wake == 0.0 and sc0.deployment.server_wake_side > 0.0
    assert any("no server thread columns recorded" in w for w in rep0["warnings"])


def test_record_sizes_are_the_runs_own(tmp_path: Path) -> None:
    """A run made with an older wire (85-byte states) is calibrated with its own record
    sizes; a run that does not record them takes this version's, warned."""
    from sigma_des.live.wire import STATE_BYTES, TRIGGER_BYTES

    old = _cpu_run(tmp_path / "old", live={"cores": CORES, "bundle": True, "load1": 0.5,
                                          "state_bytes": 85, "trigger_bytes": 21})
    sc, rep = calibrate(old, tmp_path / "fo")
    assert (sc.payload_bits, sc.trigger_payload_bits) == (85 * 8, 21 * 8)
    assert not any("record taken" in w for w in rep["warnings"])
    sc, rep = calibrate(_cpu_run(tmp_path / "new"), tmp_path / "fn")
    assert (sc.payload_bits, sc.trigger_payload_bits) == (STATE_BYTES * 8, TRIGGER_BYTES * 8)
    w = " | ".join(rep["warnings"])
    assert f"does not record 'state_bytes': this version's {STATE_BYTES}-byte" in w
    assert f"does not record 'trigger_bytes': this version's {TRIGGER_BYTES}-byte" in w
