"""The cohort core reproduces the deployment exactly (docs/concepts/engines.md,
"Deployment and CPU").

The CPU stage (bursts at publish, receive, broker service and the server's alignment
tick, on colocated or dedicated machines, with background load) and per-host MQTT
clients, alone and on top of the lossy transports of ``test_cohort_transport``. Each
case runs on both engines, whose whole results (every metric, the CPU metrics
included, links, time series) must be identical, and checks that it really exercises
what it claims to.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

import sigma_des.events.fast.driver as driver
from sigma_des import load
from sigma_des.api import run_method
from sigma_des.events.fast.support import unsupported
from sigma_des.net.cpu import RESERVATIONS, Machine
from tests.conftest import tiny
from tests.events.test_cohort import run_both
from tests.events.test_cohort_transport import _LOSSY, _STREAM

METHODS = ["none", "lockstep", "hlc", "bides"]

#: Six nodes on two hosts, random latency and step times, commands, a busy broker: every
#: process spends CPU per message, the server per tick too, on one core's worth of
#: machine slowed by background load, so bursts queue for the thread and the cores.
_BASE: dict[str, Any] = {
    "nodes": 6,
    "net.host_link.latency": {"dist": "uniform", "low": 0.0002, "high": 0.002},
    "compute.step_time": {"dist": "lognormal", "mean": 0.002, "std": 0.001},
    "commands.enabled": True,
    "broker.publish_service": {"dist": "exponential", "mean": 0.0001},
    "broker.delivery_service": 0.00004,
}
_CPU: dict[str, Any] = {
    "deployment.preset": "colocated",
    "deployment.cores": 1,
    "deployment.background": 0.25,
    "deployment.host_demand": 0.0003,
    "deployment.server_demand": 0.0002,
    "deployment.server_tick": 0.002,
}


def _exercised(m: dict[str, Any]) -> None:
    """The CPU stage did something: bursts waited for the server's thread or a core."""
    assert m["server_cpu_util"] > 0.0 and m["host_cpu_util_max"] > 0.0
    assert m["server_cpu_max_wait_ms"] > 0.0


@pytest.mark.parametrize("preset", ["colocated", "dedicated"])
@pytest.mark.parametrize("method", METHODS)
def test_cpu_stage_identical(method: str, preset: str) -> None:
    sc = tiny(**{**_BASE, **_CPU, "deployment.preset": preset})
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    _exercised(ev["metrics"])


@pytest.mark.parametrize("method", METHODS)
def test_wake_up_costs_identical(method: str) -> None:
    """Bursts that find their thread idle cost the process's wake-up more (hosts and
    server): both engines tell idle from busy threads alike."""
    sc = tiny(**{**_BASE, **_CPU, "deployment.host_wake": 0.0004,
                 "deployment.server_wake": 0.0003})
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    _exercised(ev["metrics"])
    plain = run_both(tiny(**{**_BASE, **_CPU}), method)[0]["metrics"]
    assert ev["metrics"]["server_cpu_util"] > plain["server_cpu_util"]


@pytest.mark.parametrize("clients", ["node", "host"])
@pytest.mark.parametrize("method", METHODS)
def test_outbox_identical(method: str, clients: str) -> None:
    """``lock_switch``: publishes whose burst ends while their process is busy wait in
    its outbox until it waits (or the switch is due) and then leave in order, and
    copies reaching a busy process are read in batches; both engines alike, and it
    changes the run."""
    base = {**_BASE, **_CPU, "deployment.host_wake": 0.0004, "deployment.clients": clients}
    ev, co = run_both(tiny(**{**base, "deployment.lock_switch": 0.003}), method)
    assert co["engine"]["used"] == "cohort"
    plain = run_both(tiny(**base), method)[0]["metrics"]
    assert ev["metrics"]["latency_state_mean"] != plain["latency_state_mean"]


@pytest.mark.parametrize("method", METHODS)
def test_host_clients_without_cpu_stage_identical(method: str) -> None:
    """Per-host clients alone: H trigger deliveries handed to the nodes, states, commands
    and re-requests through the host's client (one stream connection per host)."""
    sc = tiny(**{**_BASE, **_STREAM, "nodes": 5, "deployment.clients": "host"})
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] > 0


@pytest.mark.parametrize("clients", ["node", "host"])
@pytest.mark.parametrize("method", METHODS)
def test_cpu_stage_over_qos1_datagram_identical(method: str, clients: str) -> None:
    """Bursts on top of QoS 1 resends, lost and late PUBACKs, redeliveries, duplicates
    (each copy received costs a burst; a resend costs none)."""
    sc = tiny(**{**_BASE, **_LOSSY, **_CPU, "deployment.clients": clients})
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    _exercised(m)
    assert m["retransmissions"] > 0 and m["duplicates"] > 0
    if method == "lockstep":
        assert m["rerequests"] > 0


@pytest.mark.parametrize("method", METHODS)
def test_dedicated_host_clients_over_lossy_stream_identical(method: str) -> None:
    sc = tiny(**{**_BASE, **_STREAM, **_CPU, "deployment.preset": "dedicated",
                 "deployment.cores": 2, "deployment.clients": "host", "net.qos": 1})
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    _exercised(ev["metrics"])
    assert ev["metrics"]["retransmissions"] > 0


def test_growth_and_flush_paths_with_bursts_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    """No spare capacity: the event table grows and the buffers flush while bursts and
    host hand-overs hold slots."""
    monkeypatch.setattr(driver, "SLACK", 0)
    sc = tiny(**{**_BASE, **_CPU, "deployment.clients": "host", "deployment.cores": 2})
    for method in ("none", "bides"):
        _ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"


def test_saturated_server_with_adaptation_and_rollbacks_identical() -> None:
    """60 nodes on 4 host processes and the server on one 2-core machine: the server's
    receive bursts saturate its thread, BiDES adapts its rate and rolls nodes back
    (job starts and rollbacks handed to Python from host hand-overs and commands)."""
    sc = load(None, [
        "nodes=60", "hosts=4", "duration=1.5", "warmup=0.5",
        "deployment.preset='colocated'", "deployment.cores=2", "deployment.background=0.5",
        "deployment.host_demand=0.0001", "deployment.server_demand=0.0002",
        "deployment.server_tick=0.001", "deployment.clients='host'",
        "bides.theta_warp=2", "bides.hold_down=1",
    ])
    for method in METHODS:
        ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"
        m = ev["metrics"]
        assert m["server_cpu_util"] > 0.5  # the server's thread is busy most of the window
        if method == "bides":
            assert m["f_trig_min_hz"] < 100.0 and m["rollbacks"] > 0


def test_zero_demands_make_no_events() -> None:
    """A CPU stage whose demands are all zero and whose broker spends nothing changes no
    result and creates no event: the compiled run is the run without a stage."""
    idle = {**_BASE, "broker.publish_service": 0.0, "broker.delivery_service": 0.0}
    sc = tiny(**idle)
    stage = tiny(**idle, **{"deployment.preset": "dedicated"})
    ev, co = run_both(stage, "bides")
    plain = run_method(replace(sc, engine="cohort"), "bides")
    assert co["wall"]["events"] == plain["wall"]["events"]
    assert {k: v for k, v in co["metrics"].items() if "cpu" not in k} == plain["metrics"]
    assert co["metrics"]["server_cpu_util"] == 0.0


def test_bundles_fall_back_to_the_spec_engine() -> None:
    sc = tiny(**{"deployment.clients": "host", "deployment.bundle": True})
    why = unsupported(sc.run_spec(), "none")
    assert why is not None and "deployment.bundle" in why
    out = run_method(replace(sc, engine="cohort"), "none")
    assert out["engine"] == {"requested": "cohort", "used": "events", "fallback": why}


@pytest.mark.parametrize("method", ["none", "bides"])
def test_backfilled_cores_and_the_reservation_cap_identical(
    method: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two cores shared by a saturated server and three hosts: bursts wait for their
    threads far ahead, so cores hold gaps that later bursts fill (backfilling) and
    reservations pile up past the cap (its merge rule): both engines place every burst
    alike."""
    most = [0]
    reserve = Machine.reserve

    def counted(self: Machine, c: int, s: float, end: float) -> None:
        reserve(self, c, s, end)
        most[0] = max(most[0], len(self.cores[c]))

    monkeypatch.setattr(Machine, "reserve", counted)
    sc = tiny(**{**_BASE, **_CPU, "nodes": 12, "hosts": 3, "deployment.cores": 2,
                 "deployment.background": 0.0, "deployment.server_demand": 0.0012,
                 "deployment.host_demand": 0.0008})
    ev, _co = run_both(sc, method)
    assert most[0] == RESERVATIONS  # the spec engine's run filled a core to the cap
    assert ev["metrics"]["machine_cpu_util_max"] > 0.9


@pytest.mark.parametrize("preset", ["colocated", "dedicated"])
@pytest.mark.parametrize("method", METHODS)
def test_run_queue_waits_identical(method: str, preset: str) -> None:
    """Run-queue floors per process, the machine's load-window growth (Erlang C) and
    the hosts' wake-ups' parts beside the thread: both engines, every metric the same,
    and the waits really taken."""
    sc = tiny(**{**_BASE, **_CPU, "deployment.preset": preset, "deployment.cores": 2,
                 "deployment.host_wake": 0.0001, "deployment.host_runq": 0.8,
                 "deployment.server_runq": 0.5, "deployment.broker_runq": 1.2,
                 "deployment.runq_growth": True, "deployment.host_wake_side": 0.0003})
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    _exercised(m)
    assert m["server_runq_cores"] > 0.0 and m["host_runq_cores_mean"] > 0.0


@pytest.mark.parametrize("preset", ["colocated", "dedicated"])
@pytest.mark.parametrize("method", METHODS)
def test_broker_growth_alone_identical(method: str, preset: str) -> None:
    """The broker's run-queue wait growing with its machine's load, the other processes'
    floors constant (``broker_runq_growth``, as ``calibrate`` writes it): both engines,
    every metric the same, and the growth really changes the run."""
    base = {**_BASE, **_CPU, **_NET, "deployment.preset": preset,
            "deployment.runq_growth": False, "deployment.broker_runq": 0.4}
    sc = tiny(**{**base, "deployment.broker_runq_growth": True})
    ev, co = run_both(sc, method)
    # ... and with the server's growing too (as calibrate writes both)
    both = run_both(tiny(**{**base, "deployment.broker_runq_growth": True,
                            "deployment.server_runq_growth": True}), method)
    assert both[1]["engine"]["used"] == "cohort"
    assert both[0]["metrics"]["latency_state_mean"] != ev["metrics"]["latency_state_mean"]
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    _exercised(m)
    plain = run_both(tiny(**base), method)[0]["metrics"]
    assert m["latency_state_mean"] != plain["latency_state_mean"]


#: the calibrated shape (session 15): both kinds' processes two threads, a wait for the
#: interpreter lock, the side part per network wake-up, run-queue waits with growth
_NET: dict[str, Any] = {
    "deployment.cores": 2, "deployment.host_wake": 0.0001, "deployment.server_wake": 0.0002,
    "deployment.host_net_msg": 0.00005, "deployment.host_net_wake": 0.0002,
    "deployment.server_net_msg": 0.00004, "deployment.server_net_wake": 0.0003,
    "deployment.host_wake_side": 0.0002, "deployment.server_wake_side": 0.0004,
    "deployment.lock_switch": 0.002, "deployment.host_runq": 0.5,
    "deployment.server_runq": 0.3, "deployment.runq_growth": True,
}


@pytest.mark.parametrize("clients", ["node", "host"])
@pytest.mark.parametrize("method", METHODS)
def test_network_threads_identical(method: str, clients: str) -> None:
    """A process's network thread (``*_net_msg``, ``*_net_wake``): receipts read and
    stamped by it, then the loop's burst; sends written by it (out of the outbox too);
    the lock wait; the side part per network wake-up. Both engines, every metric the
    same, and the thread really changes the run."""
    base = {**_BASE, **_CPU, **_NET, "deployment.clients": clients}
    sc = tiny(**base)
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    _exercised(m)
    off = {k: 0.0 for k in _NET if "_net_" in k}
    plain = run_both(tiny(**{**base, **off}), method)[0]["metrics"]
    assert m["latency_state_mean"] != plain["latency_state_mean"]
    assert m["server_cpu_util"] != plain["server_cpu_util"]


@pytest.mark.parametrize("method", METHODS)
def test_network_threads_over_a_lossy_stream_identical(method: str) -> None:
    """The network thread on a lossy stream: copies held behind a lost segment are read
    at their own arrival, a resent one when it arrives, and the loop takes them in
    order when the gap is filled (``read_held``). Both engines, every metric the same,
    and held copies really occur (retransmissions with random latency)."""
    sc = tiny(**{**_BASE, **_CPU, **_NET, "net.host_link.loss.p": 0.05,
                 "deployment.clients": "host"})
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] > 0


@pytest.mark.parametrize("method", METHODS)
def test_network_threads_over_qos1_datagram_identical(method: str) -> None:
    """The network thread under QoS 1 resends, lost PUBACKs and duplicates (each copy
    received passes the thread; a resend does not), dedicated machines."""
    sc = tiny(**{**_BASE, **_LOSSY, **_CPU, **_NET, "deployment.preset": "dedicated"})
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] > 0 and ev["metrics"]["duplicates"] > 0
