"""Forged live messages: well-formed payloads with fields out of range, on a real broker.

Each one used to crash a host (``go:abc``), hang the hosts (a trigger for frame
2^32-1) or the parent (wrong-typed stats); now each is counted and dropped, and the
run completes with finite results from both hosts.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from sigma_des.live.broker import BrokerAddress
from sigma_des.live.loop import Client
from sigma_des.live.runner import LiveOptions, run_live
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import (
    Topics,
    Window,
    WireError,
    check_stats,
    decode_control,
    encode_command,
    encode_rerequest,
    encode_state,
    encode_trigger,
)
from tests.live.live_helpers import live_scenario, needs_mosquitto

U32 = 2**32 - 1
#: control messages: each of the 2 hosts rejects each
CONTROL = [b"go:abc", b"go:1e308", b"go:nan", b"go:" + b"9" * 50, b"halt", b"go:\xff"]
#: triggers (a well-formed payload, a field out of the run): each host rejects each
TRIGGERS = [
    encode_trigger(U32, 0.0, 0.01, -math.inf, 0),  # hung the hosts (4e9 physics steps)
    encode_trigger(150, 0.0, 0.01, -math.inf, 0),  # in the run, but not issued by now
    encode_trigger(1, 0.0, 10.0, -math.inf, 0),  # a 10 s step
    encode_trigger(1, 1e300, 0.01, -math.inf, 0),  # sent after the run
    encode_trigger(1, 0.0, 0.01, math.inf, 0),  # HLC time +inf
]
OBS = np.zeros(12)
#: states of node 0 on host 0's topic: the server rejects each
STATES = [
    encode_state(0, 2**31 - 1, 0.0, 0.0, -math.inf, 0, OBS),  # frame outside the run
    encode_state(0, 140, 0.0, 0.0, -math.inf, 0, OBS),  # a frame not triggered yet
    encode_state(0, 0, 0.0, 1e300, -math.inf, 0, OBS),  # sent after the run
    encode_state(0, 0, -1e300, 0.0, -math.inf, 0, OBS),  # generated before it
    encode_state(0, 0, 0.0, 0.0, -math.inf, 0, np.full(12, 1e30)),  # absurd state
]
#: the 4-wide commands and re-requests for host 0's node 0: host 0 rejects each
W = np.zeros(4)
COMMANDS = [
    encode_command(0, 10**6, 1, 0.0, W),  # stamp frame outside the run
    encode_command(0, -1, 1, 0.0, np.full(4, 1e300)),  # absurd command values
    encode_command(0, -1, U32, 0.0, W),  # tick outside the run
    encode_command(0, -1, 1, -1e300, W),  # sent long before the run
]
REREQS = [encode_rerequest(0, U32, 0, 0.0), encode_rerequest(0, 1, 0, 1e300)]
#: stats while the run is on (never the hosts'), and wrong-typed ones: the server rejects each
STATS = [b"[1,2", json.dumps({"host": 0, "links": "x"}).encode(), b'{"host": 0}']


def _forge(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
    """A client with valid credentials publishing well-formed but forged messages."""
    c = Client(addr, "forger", [], lambda t, p: None)
    c.start()
    for p in CONTROL:
        c.publish(tp.ctl, p, 1)
    for p in TRIGGERS:
        c.publish(tp.trig, p, 1)
    for p in STATES:
        c.publish(tp.state(0), p, 1)
    for p in COMMANDS:
        c.publish(tp.cmd(0), p, 1)
    for p in REREQS:
        c.publish(tp.rereq(0), p, 1)
    for p in STATS:
        c.publish(tp.stats(0), p, 1)
    time.sleep(0.3)
    c.stop()


@needs_mosquitto
def test_forged_messages_are_counted_and_dropped_and_the_run_completes() -> None:
    res, _msgs, _ = run_live(live_scenario(), ["bides"], LiveOptions(hook=_forge))
    m = res.methods["bides"]
    live = res.live["bides"]
    assert live["hosts_reported"] == [0, 1]  # neither host crashed or hung
    assert not res.interrupted
    hosts = 2 * (len(CONTROL) + len(TRIGGERS)) + len(COMMANDS) + len(REREQS)
    assert m["rejected"] == hosts + len(STATES) + len(STATS)
    for key in ("aoi_mean", "latency_state_mean", "snapshot_rate_hz", "missed_frac"):
        assert math.isfinite(m[key]), key
    assert m["snapshot_rate_hz"] > 0 and m["missed_frac"] < 0.5


WIN = Window.of(1.5, 100.0, 10.0)
GOOD_STATS = {"host": 0, "links": {"host0.up": [100, 2]}, "step_real_s": 0.01,
              "rollbacks": 0, "resim_steps": 0, "history_misses": 0, "rejected": 0, "resent": 0,
              "gave_up": 0, "connects": 1, "disconnects": 0, "steps": 5,
              "wake": {"wakes": 3, "calls": 7, "cpu_s": 0.002, "skk": 19.0, "skc": 0.005}}


def test_window_of_a_run() -> None:
    assert WIN.max_frame == 152  # 1.5 s at 100 Hz, plus 2
    assert WIN.dt_max == pytest.approx(0.15)  # 1.5 / f_trig_min
    WIN.frame("x", 152)
    with pytest.raises(WireError, match="frame 153 outside 0..152"):
        WIN.frame("x", 153)


def test_good_stats_pass_and_each_bad_field_is_named() -> None:
    assert check_stats(json.dumps(GOOD_STATS).encode(), 0) == GOOD_STATS
    for key, bad in [("rollbacks", -1), ("steps", "5"), ("resent", 1.5), ("rejected", True),
                     ("step_real_s", "x"), ("links", {"a": [1]}), ("links", [1, 2]),
                     ("connects", 2**60), ("wake", {"wakes": 3}),
                     ("wake", {**GOOD_STATS["wake"], "cpu_s": -1.0}),
                     ("wake", {**GOOD_STATS["wake"], "calls": 1.5})]:
        with pytest.raises(WireError, match=f"bad {key}"):
            check_stats(json.dumps({**GOOD_STATS, key: bad}).encode(), 0)
    for text in (b"NaN", b"{}", b"\xff", json.dumps({**GOOD_STATS, "x": 1}).encode(),
                 json.dumps({**GOOD_STATS, "step_real_s": math.nan}).encode()):
        with pytest.raises(WireError):
            check_stats(text, 0)
    with pytest.raises(WireError, match="host 0 is not 1"):
        check_stats(json.dumps(GOOD_STATS).encode(), 1)


def test_control_messages() -> None:
    now = 1000.0
    assert decode_control(b"go:1001.5", now) == ("go", 1001.5)
    assert decode_control(b"stop", now)[0] == "stop"
    for p in CONTROL + [b"go:900", b"go:1070", b"stop "]:
        with pytest.raises(WireError):
            decode_control(p, now)
