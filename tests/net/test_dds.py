"""Hand-computed tiny scenarios over the DDS/RTPS middleware (``net.middleware = "dds"``).

Scenario: tests/conftest.py TINY (nodes 0,1 on host 0, node 2 on host 1; host links
1 ms, server link 0.5 ms, 100 Mbps: tau = 80 ns/byte; compute 2 ms; 100 Hz) over
DDS with constant costs: writer CW = 20 us per send, reader CR = 30 us, executor
X = 1 us per entity, E = 16 endpoints (a node has E + 2 entities, the server
E + 3), metatraffic M = 5 us. One SPDP announcement per participant at its launch
(< 0.1 s), no periodic traffic before 1 s: discovery is over before the 0.2 s
warm-up, so the window holds user traffic only.

Derivation (method none, window [0.2, 1)): trigger k leaves the server thread for
node i at T + (i+1)CW (one unicast per reader, node order); the trigger DATA frame
takes WT*tau < CW on each link, so nothing queues on a link: it reaches node i at
T + (i+1)CW + 2WT*tau + LS + LH, whose thread delivers after RN = CR + X(E+2).
States are published C later, leave the node thread CW later, cross two links
(WS*tau < CW: no queueing) and reach the server CW apart in node order; the
server thread takes RS = CR + X(E+3) > CW each, so state i is delivered at
A0 + (i+1)RS.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import tiny

from sigma_des import compare
from sigma_des.events.engine import MethodRun
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.net.dds import acknack_bytes, data_bytes, heartbeat_bytes
from sigma_des.net.wire import frame_bytes

TAU = 8.0 / 100e6
LH, LS, C = 0.001, 0.0005, 0.002
CW, CR, X, E, M = 20e-6, 30e-6, 1e-6, 16, 5e-6
RN, RS = CR + X * (E + 2), CR + X * (E + 3)
MS = 1000.0

DDS = {
    "net.middleware": "dds",
    "net.transport": "datagram",
    "dds.writer_cost": CW,
    "dds.reader_cost": CR,
    "dds.executor_per_entity": X,
    "dds.endpoints": E,
    "dds.meta_cost": M,
    "dds.spdp_initial_count": 1,
    "dds.spdp_period": 5.0,
    "dds.heartbeat_period": 5.0,
}


def _frame(rtps: int) -> int:
    return frame_bytes(rtps, 28, 38)


WT, WS = _frame(data_bytes(64)), _frame(data_bytes(150))


def test_rtps_wire_sizes() -> None:
    # RTPS header 20 + INFO_DST 16 + INFO_TS 12 + DATA 24 + encapsulation 4 + payload
    assert data_bytes(64) == 20 + 16 + 12 + 24 + 4 + 8
    assert data_bytes(150) == 20 + 16 + 12 + 24 + 4 + 20  # 19 B padded to 20
    assert data_bytes(64, unicast=False) == data_bytes(64) - 16
    assert heartbeat_bytes() == acknack_bytes() == 68
    assert (WT, WS) == (150, 162)  # + UDP/IP 28 + Ethernet 38


@pytest.fixture(scope="module", params=["events", "cohort"])
def none_run(request):  # type: ignore[no-untyped-def]
    """Method none over DDS; the cohort engine falls back to the per-message one."""
    return compare(tiny(engine=request.param, methods=["none"], **DDS), progress=False)


def test_dds_latencies_and_aoi_exact(none_run) -> None:  # type: ignore[no-untyped-def]
    m = none_run.methods["none"]
    i = np.arange(3)
    lat_trig = (i + 1) * CW + 2 * WT * TAU + LS + LH + RN
    lat_state = CW + 2 * WS * TAU + LH + LS + (i + 1) * RS - i * CW
    assert m["latency_trigger_mean"] == pytest.approx(lat_trig.mean() * MS, abs=1e-9)
    assert m["latency_state_mean"] == pytest.approx(lat_state.mean() * MS, abs=1e-9)
    aoi = 0.010 - (lat_trig + C)
    assert m["aoi_mean"] == pytest.approx(aoi.mean() * MS, abs=1e-9)
    assert m["aoi_max"] == pytest.approx(aoi.max() * MS, abs=1e-9)
    # unicast: per frame 3 trigger copies up the server link + 3 down, 3 states up + 3 down
    bits = (6 * WT + 6 * WS) * 8 * 100
    assert m["throughput_mbps"] == pytest.approx(bits / 1e6, rel=1e-12)
    assert m["broker_util"] == 0.0  # no broker
    assert none_run.engines["none"]["fallback"].startswith("DDS middleware") or (
        none_run.engines["none"]["requested"] == "events"
    )


def test_multicast_trigger_is_one_send_copied_by_the_switch() -> None:
    res = compare(tiny(methods=["none"], **DDS, **{"dds.multicast": True}), progress=False)
    wm = _frame(data_bytes(64, unicast=False))
    # one send (CW), one uplink frame; host 0's downlink serializes node 0 then node 1
    r = CW + 2 * wm * TAU + LS + LH + RN + np.array([0.0, wm * TAU, 0.0])
    m = res.methods["none"]
    assert m["latency_trigger_mean"] == pytest.approx(r.mean() * MS, abs=1e-9)


def _run(method: str, **over: object) -> MethodRun:
    sc = tiny(methods=[method], **{**DDS, **over})
    run = MethodRun(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc))
    run.run()
    return run


def test_lost_state_is_repaired_after_the_next_heartbeat() -> None:
    """HEARTBEAT -> ACKNACK -> resend, each step hand-timed (one node, one host)."""
    p = 0.1
    hrd, nrd = 0.005, 0.005
    # trigger 0 (t = 0) finds no matched reader; the 0.3 s re-request restarts the loop
    run = _run(
        "lockstep", nodes=1, hosts=1, **{
            "dds.heartbeat_period": p, "lockstep.retry_timeout": 0.3,
            "faults": [{"kind": "drop", "message": "state", "node": 0, "frame": 10}],
        })
    H = run.spec.history_frames
    t50 = run.trigger.trig_time[10 % H]
    assert t50 > 0.3
    # frame 10's state leaves node 0's thread at t_sent (its trigger: one unicast send)
    t_sent = t50 + CW + 2 * WT * TAU + LS + LH + (CR + X * (E + 2)) + C + CW
    launch = run.net.launch[0]
    j = int(np.floor((t_sent - launch) / p)) + 1
    hb = _frame(heartbeat_bytes()) * TAU
    an = _frame(acknack_bytes()) * TAU
    t = launch + j * p + M  # node 0's HEARTBEAT leaves its thread
    t += 2 * hb + LH + LS + M + hrd  # server reads it, waits, answers
    t += M + 2 * an + LS + LH + M + nrd  # ACKNACK back, node 0 waits, resends
    t += CW + 2 * WS * TAU + LH + LS + CR + X * (E + 1)  # DATA again, server reads it
    assert run.trigger.trig_time[11 % H] == pytest.approx(t, abs=1e-12)
    assert t - t50 < 0.3  # repaired before the barrier's re-request
    assert run.net.retransmissions == 1
    assert run.aligner.rerequests == 1  # type: ignore[attr-defined]  # frame 0 only


def test_keep_last_history_turns_a_late_nack_into_a_gap() -> None:
    drop = {"faults": [{"kind": "drop", "message": "state", "node": 2, "frame": 40}],
            "dds.heartbeat_period": 0.25}
    # 100 Hz: ~25 newer samples are written before the NACK arrives
    shallow = _run("none", **drop, **{"dds.history_depth": 10})
    assert (shallow.net.gave_up, shallow.net.retransmissions) == (1, 0)
    deep = _run("none", **drop, **{"dds.history_depth": 100})
    assert (deep.net.gave_up, deep.net.retransmissions) == (0, 1)
    best_effort = _run("none", **drop, **{"dds.reliable": False})
    assert (best_effort.net.gave_up, best_effort.net.retransmissions) == (0, 0)


@pytest.mark.parametrize("nodes", [3, 6])
def test_discovery_is_all_to_all(nodes: int) -> None:
    run = _run("none", nodes=nodes, hosts=2)
    net = run.net
    parts = nodes + 1
    # every participant heard and matched every other: P(P-1) SEDP exchanges
    assert all(len(h) == parts - 1 for h in net.heard)  # type: ignore[attr-defined]
    assert sum(len(s) for s in net.matched) == parts * (parts - 1)  # type: ignore[attr-defined]
    # no user sample was sent to an unmatched reader after the warm-up
    assert net.dds_unmatched == 0  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("overrides", "key", "words"),
    [
        (["net.middleware='zmq'"], "net.middleware", "'mqtt' or 'dds'"),
        (["net.middleware='dds'"], "net.transport", "datagram"),
        (["net.middleware='dds'", "net.transport='datagram'"], "net.qos", "must be 0"),
        (["dds.history_depth=0"], "dds.history_depth", ">= 1"),
        (["dds.heartbeat_period=0"], "dds.heartbeat_period", "> 0"),
        (["dds.spdp_bytes=70000"], "dds.spdp_bytes", "1..65507"),
        (["dds.writer_cost=-1e-6"], "dds.writer_cost.value", ">= 0"),
        (["dds.endpoints=-1"], "dds.endpoints", ">= 0"),
        (["dds.multicast=1"], "dds.multicast", "true or false"),
        (["rpc.in_flight=-1"], "rpc.in_flight", ">= 0"),
        (["rpc.render_per_vehicle=-0.1"], "rpc.render_per_vehicle", ">= 0"),
        (["rpc.calltime=1"], "rpc.calltime", "unknown key"),
        (["methods=['rpcx']"], "methods", "rpc"),
    ],
)
def test_bad_peer_keys_exit_2_naming_the_key(
    overrides: list[str], key: str, words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from sigma_des import ConfigError, load
    from sigma_des.cli import main

    with pytest.raises(ConfigError) as ei:
        load(None, overrides)
    assert ei.value.key == key
    assert words in ei.value.reason
    args = ["compare", "--no-progress"]
    for o in overrides:
        args += ["--set", o]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert key in err and "Traceback" not in err


def test_same_seed_same_results_with_random_costs_and_loss() -> None:
    over = {**DDS, "methods": ["none", "lockstep"], "dds.heartbeat_period": 0.1,
            "dds.reader_cost": {"dist": "exponential", "mean": 3e-5},
            "net.host_link.latency": {"dist": "uniform", "low": 0.0005, "high": 0.0015},
            "net.host_link.loss": {"model": "bernoulli", "p": 0.05}}
    a = compare(tiny(**over), progress=False)
    b = compare(tiny(**over), progress=False)
    assert json.dumps(a.methods, sort_keys=True) == json.dumps(b.methods, sort_keys=True)
    assert a.methods["none"]["retransmissions"] > 0  # repairs happened
    c = compare(tiny(**over, seed=2), progress=False)
    assert c.methods["none"]["latency_state_mean"] != a.methods["none"]["latency_state_mean"]


def _deliveries(depth: int) -> tuple[MethodRun, list[tuple[int, float, float]]]:
    """Method none, one node; the state of frame 40 is lost on the server's link."""
    from sigma_des.net.kinds import STATE
    from sigma_des.net.message import Msg

    sc = tiny(methods=["none"], nodes=1, hosts=1, **{
        **DDS, "dds.heartbeat_period": 0.1, "dds.history_depth": depth,
        "faults": [{"kind": "drop", "message": "state", "node": 0, "frame": 40}]})
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc))
    got: list[tuple[int, float, float]] = []
    inner = run.net.deliver

    def record(m: Msg) -> None:
        if m.kind == STATE:
            got.append((m.index, run.kernel.now, m.t_pub))
        inner(m)

    run.net.deliver = record
    run.run()
    return run, got


@pytest.mark.parametrize("depth", [100, 2])
def test_reliable_reader_holds_later_samples_behind_a_lost_one(depth: int) -> None:
    run, got = _deliveries(depth)
    frames = [f for f, _t, _p in got]
    assert frames == sorted(frames)  # in order, always
    when = {f: t for f, t, _p in got}
    pub = {f: p for f, _t, p in got}
    held = [f for f in frames if f > 40 and when[f] == when[41]]
    assert len(held) >= 2  # later frames waited behind frame 40 ...
    assert when[41] - pub[41] > 0.010  # ... far longer than a delivery takes (~3 ms)
    assert when[max(held) + 1] - pub[max(held) + 1] < 0.005
    assert max(held) + 1 in when and when[max(held) + 1] > when[41]
    if depth == 100:  # repaired: frame 40 is delivered first, at the same instant
        assert when[40] == when[41] and run.net.retransmissions == 1
    else:  # out of the history: a GAP releases the held frames; 40 is never delivered
        assert 40 not in when and run.net.gave_up == 1
