"""One loop, two clocks: the DES and the live processes run the same rules.

The same scenario is run through the DES (:class:`MethodRun` on the SimPy kernel,
messages as events and in the compiled core) and through the live server and hosts
(:class:`LiveServer`, :class:`Host`: their codecs, topics and handlers) on one
virtual clock (:class:`VirtualLoop`) with a deterministic in-process MQTT stand-in
(no broker: a message takes its publisher's access-link latency to the "broker"
and its subscriber's from there, as in the DES with a bandwidth so high that a
packet's serialization is below a float's resolution of the times, and no
broker service time). With the same constant latencies and step times, the two
must issue the same triggers at the same times, show the same frames at every
alignment tick and sample the same AoI, exactly, for every method. This is the
test a tick-phase, trigger-grid or job-cost rule restated on one side only fails.

Over a lossy stream the live processes' link shim (:mod:`sigma_des.live.shim`) stands
in for the links: it draws each try's loss as the DES does, resends by the transport's
rule (``rto · 2^attempt``, a give-up after ``max_retries``) and keeps each connection in
order, so a resend rule or in-order release restated on one side fails that case.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from paho.mqtt.client import topic_matches_sub

from sigma_des import load
from sigma_des.config import Scenario
from sigma_des.events.engine import MethodRun
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.live.broker import BrokerAddress
from sigma_des.live.host import Host
from sigma_des.live.loop import VirtualLoop
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import Topics

L_HOST = 0.00025  # host access link, one way (s)
L_SERVER = 0.0003  # server access link, one way (s)

#: 6 nodes on 2 hosts of 1 core; a node's step (4 ms) x 3 nodes > the 10 ms period:
#: jobs queue on the core, triggers coalesce into catch-up jobs, Lock-Step's barrier
#: comes late, BiDES lowers its rate; commands every 3rd tick (formation), and with
#: Θ_warp = 2 frames BiDES's late commands roll nodes back (time warp).
SETS = [
    "nodes=6", "hosts=2", "cores_per_host=1", "f_trig=100", "f_align=60", "f_render=60",
    "duration=1.5", "warmup=0.25", 'engine="events"',
    'compute.step_time.dist="constant"', "compute.step_time.value=0.004",
    f"net.host_link.latency.value={L_HOST}", f"net.server_link.latency.value={L_SERVER}",
    "net.host_link.bandwidth_mbps=1e20", "net.server_link.bandwidth_mbps=1e20",
    "broker.publish_service.value=0.0", "broker.delivery_service.value=0.0",
    "bides.theta_warp=2",
]
METHODS = ["none", "lockstep", "hlc", "bides"]


class _Recorded:
    """Records, through the server's own hooks, what the equivalence compares."""

    triggers: list[tuple[int, float, float]]
    ticks: list[tuple[float, int, list[int], list[float]]]

    def on_frame(self, k: int, t: float, dt: float) -> None:
        self.triggers.append((k, t, dt))
        super().on_frame(k, t, dt)  # type: ignore[misc]

    def align(self) -> None:
        t = self.clock.now  # type: ignore[attr-defined]
        super().align()  # type: ignore[misc]
        if t < self.spec.duration:  # type: ignore[attr-defined]
            al = self.aligner  # type: ignore[attr-defined]
            gen = np.where(np.isnan(al.shown_gen), -1.0, al.shown_gen)  # -1: none shown
            self.ticks.append((t, al.aligned_frame, al.shown_frame.tolist(), gen.tolist()))


class DesServer(_Recorded, MethodRun):
    """The DES, recorded."""


class VirtualLiveServer(_Recorded, LiveServer):
    """The live server, recorded."""


class _Client:
    """What the live processes use of a paho client, delivering through :class:`_Wire`."""

    def __init__(self, wire: _Wire, latency: float, subs: list[tuple[str, int]],
                 on_message: Callable[[str, bytes], None]) -> None:
        self.wire = wire
        self.latency = latency
        self.subs = [s for s, _q in subs]
        self.on_message = on_message
        self.connects = 1
        self.disconnects = 0

    def publish(self, topic: str, payload: bytes, qos: int) -> None:
        loop = self.wire.loop
        loop.call_at(loop.now + self.latency, self.wire.route, topic, payload)


class _Wire:
    """In-process MQTT: up the publisher's link, then down each subscriber's, in
    subscription order (the broker's fan-out order); nothing lost, nothing reordered."""

    def __init__(self, loop: VirtualLoop) -> None:
        self.loop = loop
        self.clients: list[_Client] = []

    def factory(self, latency: float) -> Callable[..., _Client]:
        def make(subs: list[tuple[str, int]], on_message: Callable[[str, bytes], None]) -> _Client:
            c = _Client(self, latency, subs, on_message)
            self.clients.append(c)
            return c
        return make

    def route(self, topic: str, payload: bytes) -> None:
        loop = self.loop
        for c in self.clients:
            if any(topic_matches_sub(s, topic) for s in c.subs):
                loop.call_at(loop.now + c.latency, c.on_message, topic, payload)


def run_des(sc: Scenario, method: str, compiled: bool = False) -> DesServer:
    run = DesServer(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc),
                    compiled=compiled)
    run.triggers, run.ticks = [], []
    run.run()
    return run


def run_live(sc: Scenario, method: str, impair: bool = False
             ) -> tuple[VirtualLiveServer, list[Host]]:
    """The live server and hosts on one virtual clock; ``impair``: the processes' link
    shims carry the links' latency and loss (the wire adds no time), else the wire
    carries the latencies."""
    loop = VirtualLoop()
    wire = _Wire(loop)
    topics = Topics("eq")
    cfg = {"qos": 1, "impair": impair, "step_delay": True, "max_inflight": 0}
    addr = BrokerAddress("127.0.0.1", 1)  # never connected: the wire stands in
    l_srv, l_host = (0.0, 0.0) if impair else (L_SERVER, L_HOST)
    srv = VirtualLiveServer(sc, method, wire.factory(l_srv), topics, 1, impair, loop=loop)
    srv.triggers, srv.ticks = [], []
    hosts = [Host(sc, method, h, cfg, topics, addr, 0.0, client_factory=wire.factory(l_host),
                  loop=loop) for h in range(sc.hosts)]
    srv.start()
    loop.run(until=sc.duration)
    return srv, hosts


def _aoi(run: Any) -> NDArray[np.float64]:
    return run.collector.aoi_samples()  # type: ignore[no-any-return]


#: drawn step times too: both sides cost a job with the same keyed draws
LOGNORMAL = ['compute.step_time.dist="lognormal"', "compute.step_time.mean=0.004",
             "compute.step_time.std=0.001"]


@pytest.mark.parametrize("step", ["constant", "lognormal"])
@pytest.mark.parametrize("method", METHODS)
def test_live_rules_on_a_virtual_clock_equal_the_des(method: str, step: str) -> None:
    sc = load(None, SETS + (LOGNORMAL if step == "lognormal" else []))
    live, hosts = run_live(sc, method)
    for compiled in (False, True):  # the per-message engine and the compiled core
        _assert_equal(run_des(sc, method, compiled), live, hosts)
    # the nodes did the same work: the same newest frames (the per-message engine's nodes)
    des = run_des(sc, method)
    assert [h.jobs.frame for h in hosts] == [des.nodes.frame[:3], des.nodes.frame[3:]]
    assert sum(h.jobs.history_misses for h in hosts) == des.nodes.history_misses


#: 7 % of the tries lost on every link, both ways, over a stream (one MQTT client per
#: host, as live): resent after 20 ms, then 40 ms; a message lost three times is given up.
LOSSY = ['deployment.clients="host"', 'net.transport="stream"', "net.rto=0.02",
         "net.max_retries=2", "net.host_link.loss.p=0.07", "net.server_link.loss.p=0.07"]


@pytest.mark.parametrize("method", METHODS)
def test_live_over_a_lossy_stream_equals_the_des(method: str) -> None:
    sc = load(None, SETS + LOSSY)
    live, hosts = run_live(sc, method, impair=True)
    shims = [live.impair] + [h.impair for h in hosts]
    for compiled in (False, True):
        des = run_des(sc, method, compiled)
        _assert_equal(des, live, hosts, min_triggers=40)  # Lock-Step's barriers wait
        # the same tries lost, resent and given up (lost = resent + given up)
        assert sum(s.resent for s in shims) == des.net.retransmissions > 30
        assert sum(s.gave_up for s in shims) == des.net.gave_up
        assert sum(s.lost for s in shims) == des.net.retransmissions + des.net.gave_up
    if method == "none":  # a message lost on all three tries
        assert des.net.gave_up == 1
    if method == "lockstep":  # re-requested states answered over the lossy links
        assert des.aligner.report().rerequests > 10


def _assert_equal(des: DesServer, live: VirtualLiveServer, hosts: list[Host],
                  min_triggers: int = 50) -> None:
    assert len(des.triggers) > min_triggers and len(des.ticks) > 60
    assert live.triggers == des.triggers
    assert live.ticks == des.ticks
    assert np.array_equal(_aoi(live), _aoi(des))
    assert _aoi(des).size > 100
    ts_live, ts_des = live.collector.ts, des.collector.ts
    assert ts_live.keys() == ts_des.keys()
    for key in ts_des:  # render ticks: times, AoI mean/max, spread, rate, frames
        assert np.array_equal(ts_live[key], ts_des[key], equal_nan=True), key
    assert sum(h.truth.rollbacks for h in hosts) == des.truth.rollbacks
    assert sum(h.truth.resim_steps for h in hosts) == des.truth.resim_steps


def test_the_scenario_exercises_what_it_claims() -> None:
    """Catch-up jobs, a late Lock-Step barrier and BiDES's rate change all happen."""
    sc = load(None, SETS)
    bides = run_des(sc, "bides")
    assert bides.f_trig < sc.f_trig  # the rate came down
    assert bides.truth.rollbacks > 10  # late commands rolled nodes back
    assert len({dt for _k, _t, dt in bides.triggers}) > 1
    lock = run_des(sc, "lockstep")
    gaps = np.diff([t for _k, t, _dt in lock.triggers])
    assert gaps.max() > 1.0 / sc.f_trig + 1e-9  # barriers completed after the grid time
    none = run_des(sc, "none")
    # a node serves 3 x 4 ms per 10 ms frame: it falls behind and coalesces triggers
    assert none.nodes.frame[0] < none.trigger.latest - 1
