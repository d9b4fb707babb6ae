"""Live reliability: rogue payloads, a broker crash, a host crash, Ctrl-C."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sigma_des.live.broker import BrokerAddress
from sigma_des.live.loop import Client
from sigma_des.live.runner import LiveOptions, run_live
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import Topics, encode_state, encode_trigger
from tests.live.live_helpers import LIVE_SETS, live_scenario, needs_mosquitto

pytestmark = needs_mosquitto


def _rogue(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
    """A client with valid credentials publishing garbage (QoS 1, so all of it arrives)."""
    c = Client(addr, "rogue", [], lambda t, p: None)
    c.start()
    good = encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))
    for payload in (good[:-3], good + b"xx", encode_state(0, 1, 0.0, 0.0, 0.0, 0,
                                                          np.full(12, math.nan)),
                    encode_state(3, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))):  # node 3 is on host 1
        c.publish(tp.state(0), payload, 1)
    c.publish(f"{tp.base}/up/h0/garbage", b"x", 1)  # unknown leaf
    c.publish(f"{tp.base}/up/h7/state", good, 1)  # no host 7
    c.publish(tp.trig, b"\x01short", 1)  # each of the 2 hosts rejects these two
    c.publish(tp.trig, encode_trigger(1, math.nan, 0.01, 0.0, 0), 1)
    c.publish(tp.cmd(0), b"\x03" * 30, 1)  # host 0 rejects it
    time.sleep(0.3)
    c.stop()


def test_rogue_payloads_are_counted_and_dropped() -> None:
    res, _msgs, _ = run_live(live_scenario(), ["bides"], LiveOptions(hook=_rogue))
    m = res.methods["bides"]
    assert m["rejected"] == 4 + 2 * 2 + 1
    assert m["unknown_topic"] == 2
    assert m["snapshot_rate_hz"] > 0 and not res.interrupted


def test_broker_killed_mid_run_reconnects_and_shows_the_gap() -> None:
    sc = live_scenario("duration=3.0", "warmup=0.2")
    res, _msgs, _ = run_live(sc, ["none"], LiveOptions(kill_broker_at=0.8, broker_down_s=0.4))
    m = res.methods["none"]
    assert m["reconnects"] >= 3  # the server and both hosts came back
    assert m["stalls"] >= 1 and m["stall_time_s"] >= 0.4
    assert m["missed_frac"] > 0.05
    # after the gap, snapshots flow again
    ts = res.timeseries["none"]
    assert ts["aligned_frame"][-1] > ts["aligned_frame"][np.searchsorted(ts["t"], 1.2)]


def test_host_killed_lockstep_stalls_bides_excludes() -> None:
    sc = live_scenario("duration=2.0", "warmup=0.2")
    res, _m, _ = run_live(sc, ["lockstep"], LiveOptions(kill_host_at=(1, 0.8)))
    lock = res.methods["lockstep"]
    assert res.live["lockstep"]["hosts_killed"] == [1]
    assert lock["stall_time_s"] > 0.8  # no eviction configured: the barrier waits for good
    res, _m, _ = run_live(sc, ["bides"], LiveOptions(kill_host_at=(1, 0.8)))
    ts = res.timeseries["bides"]
    assert res.methods["bides"]["stall_time_s"] < 0.5
    assert ts["aligned_frame"][-1] > ts["aligned_frame"][np.searchsorted(ts["t"], 1.0)] + 20


def _alive(pid: int) -> bool:
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().lower()
    except OSError:
        return False


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-e", "-o", "pid=,ppid="], capture_output=True, text=True).stdout
    return [int(a) for a, b in (ln.split() for ln in out.splitlines()) if int(b) == pid]


def test_ctrl_c_writes_partial_results_and_stops_everything(tmp_path: Path) -> None:
    out = tmp_path / "out"
    sets = [a for s in LIVE_SETS[:2] for a in ("--set", s)] + ["--set", "duration=30"]
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    p = subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "live", *sets, "--methods",
                          "none", "--out", str(out)], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    try:
        assert p.stderr is not None
        line = p.stderr.readline().decode()  # printed once the hosts are ready
        assert "hosts ready, running" in line, line
        kids = _children(p.pid)
        assert len(kids) == 5  # the broker, 2 hosts, the janitor and the CPU-mark helper
        time.sleep(1.0)
        p.send_signal(signal.SIGINT)
        code = p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert code == 130, p.stderr.read() if p.stderr else ""
    summ = json.loads((out / "summary.json").read_text())
    assert summ["interrupted"] is True and summ["mode"] == "live"
    assert (out / "messages.csv.gz").exists()
    time.sleep(0.5)
    assert [k for k in kids if _alive(k)] == []


def test_killed_sigma_des_takes_its_broker_and_hosts_along(tmp_path: Path) -> None:
    sets = [a for s in LIVE_SETS[:2] for a in ("--set", s)] + ["--set", "duration=30"]
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    p = subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "live", *sets, "--methods",
                          "none"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        assert p.stderr is not None
        assert "hosts ready, running" in p.stderr.readline().decode()
        kids = _children(p.pid)
        assert len(kids) == 5  # the broker, 2 hosts, the janitor and the CPU-mark helper
        p.kill()  # SIGKILL: no clean-up code runs; PR_SET_PDEATHSIG must
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
    deadline = time.monotonic() + 10.0
    alive = kids
    while alive and time.monotonic() < deadline:
        time.sleep(0.1)
        alive = [k for k in kids if _alive(k)]
    assert alive == []
