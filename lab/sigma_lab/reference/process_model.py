"""An idiomatic one-process-per-message SimPy model of the sigma_des loop.

This is the *baseline* of ``experiments/bench_engine.py``: an independent
re-implementation of the model contract (``docs/concepts/model.md``, "Components and message
flow" and "Network") for a restricted scenario class, written the textbook SimPy
way, so that the engine's speed can be compared with it and its metrics
cross-checked against it:

* every message is a process (``env.process``): one per PUBLISH (uplink hop,
  broker service, fan-out), one per delivery (downlink hop, in-order release,
  application hand-off), one per stream PUBACK, one per node computation;
* the broker is a ``simpy.Resource(capacity=1)`` held for ``publish_service``
  and then for one ``delivery_service`` per subscriber (delivery ``j`` leaves
  when its part of the service ends);
* every link direction is a ``simpy.Resource(capacity=1)`` held for the
  serialization time ``bytes·8/bandwidth``, then ``yield env.timeout(latency)``;
* every host's cores are a ``simpy.Resource(capacity=cores_per_host)`` (FCFS);
  a node that is queued or computing coalesces newer triggers and catches up in
  its next job;
* stream transport (per-connection in-order delivery) is an event chain: a
  message waits for the previous message of its connection to be handed over.

The only non-textbook detail is the tie rule of the model contract ("message
arrivals before trigger issue before alignment before render at equal times"):
arrivals, computation ends, trigger ticks, alignment ticks and render ticks are
timeouts scheduled with SimPy priorities 0, 0, 1, 2, 3 through the public
``Environment.schedule`` (:class:`PTimeout`).

Random numbers come from the project's counter-based streams with the engine's
keys (stream ``lat.host.up`` … keyed ``(kind, subject, index, attempt)``,
``svc.publish``/``svc.delivery``, step times from ``compute`` keyed ``(0, node,
frame, 0)``), so both implementations see the very same draws. The draws of one
``(kind, index, attempt)`` are made for all subjects at once and cached (RNG
cost is not what this baseline is about; the values are the same either way).

Supported scenarios (:func:`check_supported`): method ``none``, transport
``stream`` without loss, QoS 0 or 1, no faults, commands disabled. The dynamics
are stepped once per trigger for the whole swarm (as the engine does) so that
both implementations do the same physics work and ``pos_err`` can be compared.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Generator
from typing import Any

import numpy as np
import simpy
from numpy.typing import NDArray
from simpy.events import EventPriority

from sigma_des.config import Scenario
from sigma_des.core.rng import RandomStreams
from sigma_des.factory import make_dynamics
from sigma_des.net.latency import Dist
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, payload_bytes, publish_bytes

__all__ = ["ProcessModel", "PTimeout", "Unsupported", "check_supported", "run_baseline"]

# Tie order at equal times (model contract): smaller runs first.
P_ARRIVAL = 0
P_TRIGGER = 1
P_ALIGN = 2
P_RENDER = 3

# Message kinds: the integers are part of the random-draw keys, so they are the
# engine's (sigma_des.net.network): trigger 1, state 2; step draws use kind 0.
K_TRIGGER = 1
K_STATE = 2
K_STEP = 0

Proc = Generator[simpy.Event, Any, None]


class Unsupported(ValueError):
    """The scenario is outside the class this baseline implements."""


def check_supported(sc: Scenario, method: str = "none") -> None:
    """Raise :class:`Unsupported` naming every feature this baseline lacks."""
    bad: list[str] = []
    if method != "none":
        bad.append(f"method {method!r} (only 'none')")
    if sc.net.transport != "stream":
        bad.append(f"transport {sc.net.transport!r} (only 'stream')")
    for name, link in (("host_link", sc.net.host_link), ("server_link", sc.net.server_link)):
        if link.loss.model != "bernoulli" or link.loss.p != 0.0:
            bad.append(f"net.{name}.loss (only no loss)")
    if sc.net.qos not in (0, 1):
        bad.append(f"qos {sc.net.qos}")
    if sc.faults:
        bad.append("faults")
    if sc.commands.enabled:
        bad.append("commands.enabled (only false)")
    if bad:
        raise Unsupported("baseline does not support: " + "; ".join(bad))


class PTimeout(simpy.Event):
    """``env.timeout(delay)`` with an explicit SimPy scheduling priority."""

    def __init__(self, env: simpy.Environment, delay: float, priority: int) -> None:
        super().__init__(env)
        self._ok = True
        self._value = None
        env.schedule(self, EventPriority(priority), delay)


class _Draws:
    """Keyed draws of one distribution from one named stream (cached per key)."""

    def __init__(self, dist: Dist, streams: RandomStreams, name: str, n_subjects: int) -> None:
        self.dist = dist
        self.stream = streams.stream(name)
        self.const = dist.value if dist.dist == "constant" else None
        self.subjects = np.arange(n_subjects, dtype=np.int64)
        self.cache: OrderedDict[tuple[int, int, int], list[float]] = OrderedDict()

    def __call__(self, kind: int, subject: int, index: int, attempt: int = 0) -> float:
        if self.const is not None:
            return self.const
        key = (kind, index, attempt)
        vec = self.cache.get(key)
        if vec is None:
            vec = self.dist.sample(self.stream, kind, self.subjects, index, attempt).tolist()
            self.cache[key] = vec
            if len(self.cache) > 4096:
                self.cache.popitem(last=False)
        return vec[subject]


class _Link:
    """One direction of one access link: a capacity-1 resource plus byte counts."""

    def __init__(self, env: simpy.Environment, name: str, mbps: float) -> None:
        self.name = name
        self.res = simpy.Resource(env, capacity=1)
        self.sec_per_byte = 8.0 / (mbps * 1e6)
        self.bytes = 0
        self.packets = 0


class _Conn:
    """One direction of one client's stream connection: the last message's hand-off."""

    __slots__ = ("last",)

    def __init__(self) -> None:
        self.last: simpy.Event | None = None


class ProcessModel:
    """The restricted scenario, one SimPy process per message.

    Args:
        sc: the scenario (see :func:`check_supported`).
    """

    def __init__(self, sc: Scenario) -> None:
        check_supported(sc)
        self.sc = sc
        self.env = simpy.Environment()
        self.sim_events = 0  # processes + timeouts + resource requests created
        n = self.n = sc.nodes
        self.server = n
        self.w0 = sc.warmup
        env = self.env
        net = sc.net
        streams = RandomStreams(sc.seed)
        nsub = n + 1
        # links: hosts 0..H-1 and the server's link
        self.host_of = sc.host_of
        self.up: list[_Link] = []
        self.down: list[_Link] = []
        for h in range(sc.hosts + 1):
            spec = net.host_link if h < sc.hosts else net.server_link
            nm = f"host{h}" if h < sc.hosts else "server"
            self.up.append(_Link(env, f"{nm}.up", spec.bandwidth_mbps))
            self.down.append(_Link(env, f"{nm}.down", spec.bandwidth_mbps))
        link_of = self.host_of + [sc.hosts]
        self.up_of = [self.up[h] for h in link_of]
        self.down_of = [self.down[h] for h in link_of]
        self.lat: dict[tuple[bool, bool], _Draws] = {}
        for is_server, spec in ((False, net.host_link), (True, net.server_link)):
            for upward in (True, False):
                tag = f"{'server' if is_server else 'host'}.{'up' if upward else 'down'}"
                self.lat[is_server, upward] = _Draws(spec.latency_of(upward), streams,
                                                     f"lat.{tag}", nsub)
        self.svc_pub = _Draws(sc.broker.publish_service, streams, "svc.publish", nsub)
        self.svc_del = _Draws(sc.broker.delivery_service, streams, "svc.delivery", nsub)
        self.step_time = _Draws(sc.compute.step_time, streams, "compute", n)
        self.broker = simpy.Resource(env, capacity=1)
        self.cores = [simpy.Resource(env, capacity=sc.cores_per_host) for _ in range(sc.hosts)]
        self.conn_up = [_Conn() for _ in range(nsub)]
        self.conn_down = [_Conn() for _ in range(nsub)]
        self.qos1 = net.qos == 1
        overhead = (net.tcpip_bytes, net.ethernet_bytes)
        qos = 1 if self.qos1 else 0
        self.trigger_bytes = frame_bytes(
            publish_bytes(net.topic_bytes, payload_bytes(sc.trigger_payload_bits), qos), *overhead
        )
        self.state_bytes = frame_bytes(
            publish_bytes(net.topic_bytes, payload_bytes(sc.payload_bits), qos), *overhead
        )
        self.ack_bytes = frame_bytes(PUBACK_BYTES, *overhead)
        # physics (stepped at trigger issue for the whole swarm, as in the model)
        self.dyn = make_dynamics(sc)
        self.phys = self.dyn.initial_state(n)
        self.cmd = self.dyn.default_command(self.phys)
        self.obs_of_frame: dict[int, NDArray[np.float64]] = {}
        # nodes
        self.node_req = [-1] * n
        self.node_frame = [-1] * n
        self.node_busy = [False] * n
        # alignment server (method none): newest state per node, shown at align ticks
        self.recv_frame = [-1] * n
        self.recv_gen = [math.nan] * n
        self.recv_obs: dict[int, NDArray[np.float64]] = {}
        self.dirty = False
        self.shown_frame = np.full(n, -1, dtype=np.int64)
        self.shown_gen = np.full(n, np.nan)
        self.shown_obs = np.full((n, 12), np.nan)
        # measurements
        self.triggers = 0
        self.messages = 0
        self.lat_state: list[float] = []
        self.lat_trigger: list[float] = []
        self.aoi_samples: list[NDArray[np.float64]] = []
        self.spread: list[int] = []
        self.pos_err: list[NDArray[np.float64]] = []
        self.snapshots = 0
        self._aoi_gen = [math.nan] * n  # for the exact time-average AoI
        self._aoi_acc = [math.nan] * n
        self._aoi_start = [math.nan] * n
        self._aoi_area = 0.0
        self._peak_sum = 0.0
        self._peak_n = 0

    # ------------------------------------------------------------ SimPy helpers

    def _process(self, gen: Proc) -> None:
        self.sim_events += 1
        self.env.process(gen)

    def _timeout(self, delay: float) -> simpy.Event:
        self.sim_events += 1
        return self.env.timeout(delay)

    def _ptimeout(self, delay: float, priority: int) -> simpy.Event:
        self.sim_events += 1
        return PTimeout(self.env, delay, priority)

    def _transmit(self, link: _Link, nbytes: int) -> Proc:
        """Serialize one packet on ``link`` (FIFO): hold it for bytes·8/bandwidth."""
        if self.env.now >= self.w0:
            link.bytes += nbytes
            link.packets += 1
        self.sim_events += 1
        with link.res.request() as req:
            yield req
            yield self._timeout(nbytes * link.sec_per_byte)

    # ------------------------------------------------------------ periodic processes

    def trigger_source(self) -> Proc:
        """Time Step Trigger: issue trigger k at T_k = k / f_trig, stepping the true swarm.

        ``env.timeout(T_next - now)`` lands exactly on ``T_next`` (the difference
        of two floats within a factor 2 of each other is exact).
        """
        sc = self.sc
        dt = 1.0 / sc.f_trig
        nodes = np.arange(self.n)
        subs = tuple(range(self.n))
        k = 0
        while True:
            t = self.env.now
            self.phys = self.dyn.step(self.phys, self.cmd, dt, k, nodes)
            self.obs_of_frame[k] = self.dyn.observe(self.phys)
            self.obs_of_frame.pop(k - 1024, None)
            if t >= self.w0:
                self.triggers += 1
            self._process(
                self.publish(self.server, K_TRIGGER, self.server, k, k, self.trigger_bytes, subs)
            )
            k += 1
            yield self._ptimeout(k / sc.f_trig - t, P_TRIGGER)  # drift-free: T_k = k / f

    def aligner(self) -> Proc:
        """Alignment ticks (method none): show each node's newest received state."""
        tick = 0
        yield self._ptimeout(self.sc.align_phase / self.sc.f_align, P_ALIGN)
        while True:
            t = self.env.now
            if self.dirty:
                self.dirty = False
                if t >= self.w0:
                    self.snapshots += 1
                for i in range(self.n):
                    g = self.recv_gen[i]
                    if g == g and not g == self.shown_gen[i]:
                        self._aoi_update(t, i, g)
                        self.shown_gen[i] = g
                        self.shown_frame[i] = self.recv_frame[i]
                        self.shown_obs[i] = self.recv_obs[i]
            tick += 1
            yield self._ptimeout((tick + self.sc.align_phase) / self.sc.f_align - t, P_ALIGN)

    def renderer(self) -> Proc:
        """Render ticks: sample AoI, frame spread and position error of the shown snapshot."""
        tick = 0
        yield self._ptimeout(self.sc.render_phase / self.sc.f_render, P_RENDER)
        while True:
            t = self.env.now
            if t >= self.w0:
                valid = ~np.isnan(self.shown_gen)
                self.aoi_samples.append(t - self.shown_gen[valid])
                if valid.any():
                    fr = self.shown_frame[valid]
                    self.spread.append(int(fr.max() - fr.min()))
                    truth = self.obs_of_frame.get(int(self.shown_frame.max()))
                    if truth is not None:
                        d = self.shown_obs[valid, 9:12] - truth[valid, 9:12]
                        e = np.sqrt((d * d).sum(axis=1))
                        self.pos_err.append(e[~np.isnan(e)])
                else:
                    self.spread.append(0)
            tick += 1
            yield self._ptimeout((tick + self.sc.render_phase) / self.sc.f_render - t, P_RENDER)

    def _aoi_update(self, t: float, i: int, g: float) -> None:
        old = self._aoi_gen[i]
        if old == old:
            a = self._aoi_acc[i]
            if t > a:
                self._aoi_area += (t - a) * (0.5 * (t + a) - old)
                self._aoi_acc[i] = t
            if t >= self.w0:
                self._peak_sum += t - old
                self._peak_n += 1
        else:
            self._aoi_acc[i] = self._aoi_start[i] = max(t, self.w0)
        self._aoi_gen[i] = g

    # ------------------------------------------------------------ messages

    def publish(
        self,
        client: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        nbytes: int,
        subs: tuple[int, ...],
    ) -> Proc:
        """One MQTT PUBLISH: uplink hop, in-order arrival, broker service, fan-out."""
        env = self.env
        t_pub = env.now
        conn = self.conn_up[client]
        prev, mine = conn.last, env.event()
        conn.last = mine
        yield from self._transmit(self.up_of[client], nbytes)
        lat = self.lat[client == self.server, True](kind, subject, index)
        yield self._ptimeout(lat, P_ARRIVAL)
        if prev is not None:
            yield prev  # stream: wait for the previous segment of this connection
        mine.succeed()
        self.sim_events += 1
        with self.broker.request() as req:
            yield req
            yield self._timeout(self.svc_pub(kind, subject, index))
            if self.qos1:
                self._process(self._transmit(self.down_of[client], self.ack_bytes))
            broadcast = subject == self.server
            for sub in subs:
                dsubj = sub if broadcast else subject
                yield self._timeout(self.svc_del(kind, dsubj, index))
                self._process(self.deliver(sub, kind, dsubj, index, payload, nbytes, t_pub))

    def deliver(
        self,
        sub: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        nbytes: int,
        t_pub: float,
    ) -> Proc:
        """One delivery broker → ``sub``: downlink hop, in-order arrival, PUBACK, hand-off."""
        env = self.env
        conn = self.conn_down[sub]
        prev, mine = conn.last, env.event()
        conn.last = mine
        yield from self._transmit(self.down_of[sub], nbytes)
        lat = self.lat[sub == self.server, False](kind, subject, index)
        yield self._ptimeout(lat, P_ARRIVAL)
        if prev is not None:
            yield prev
        if self.qos1:
            self._process(self._transmit(self.up_of[sub], self.ack_bytes))
        t = env.now
        if t_pub >= self.w0:
            self.messages += 1
            (self.lat_state if kind == K_STATE else self.lat_trigger).append(t - t_pub)
        if sub == self.server:
            frame, gen, obs = payload
            if frame > self.recv_frame[subject]:
                self.recv_frame[subject] = frame
                self.recv_gen[subject] = gen
                self.recv_obs[subject] = obs
                self.dirty = True
        elif payload > self.node_req[sub]:
            self.node_req[sub] = payload
            if not self.node_busy[sub]:
                self.node_busy[sub] = True
                self._process(self.node_job(sub))
        mine.succeed()

    def node_job(self, i: int) -> Proc:
        """Node ``i`` computes up to its newest trigger on a host core, publishing each result."""
        cores = self.cores[self.host_of[i]]
        while self.node_req[i] > self.node_frame[i]:
            target = self.node_req[i]
            cost = 0.0
            for f in range(self.node_frame[i] + 1, target + 1):
                cost += self.step_time(K_STEP, i, f)
            self.sim_events += 1
            with cores.request() as req:
                yield req
                yield self._ptimeout(cost, P_ARRIVAL)
            self.node_frame[i] = target
            gen = self.env.now
            obs = self.obs_of_frame[target][i].copy()
            self._process(
                self.publish(
                    i, K_STATE, i, target, (target, gen, obs), self.state_bytes, (self.server,)
                )
            )
        self.node_busy[i] = False

    # ------------------------------------------------------------ run

    def run(self) -> dict[str, float]:
        """Run to ``duration``; return the metrics (same names and units as the engine)."""
        sc = self.sc
        self._process(self.trigger_source())
        self._process(self.aligner())
        self._process(self.renderer())
        self.env.run(until=sc.duration)
        return self.metrics()

    def metrics(self) -> dict[str, float]:
        sc = self.sc
        window = sc.duration - self.w0
        ms = 1000.0
        m: dict[str, float] = {}
        aoi = np.concatenate(self.aoi_samples) if self.aoi_samples else np.empty(0)
        m["aoi_mean"] = float(aoi.mean()) * ms if aoi.size else math.nan
        m["aoi_p99"] = float(np.percentile(aoi, 99.0)) * ms if aoi.size else math.nan
        m["aoi_max"] = float(aoi.max()) * ms if aoi.size else math.nan
        # time-average AoI: close every node's sawtooth at the end of the window
        area, node_time = self._aoi_area, 0.0
        for i in range(self.n):
            g = self._aoi_gen[i]
            if g == g:
                acc, end = self._aoi_acc[i], sc.duration
                if end > acc:
                    area += (end - acc) * (0.5 * (end + acc) - g)
                node_time += max(end - self._aoi_start[i], 0.0)
        m["aoi_time_avg"] = area / node_time * ms if node_time > 0 else math.nan
        m["aoi_peak_mean"] = self._peak_sum / self._peak_n * ms if self._peak_n else math.nan
        for name, xs in (("state", self.lat_state), ("trigger", self.lat_trigger)):
            lat = np.asarray(xs)
            m[f"latency_{name}_mean"] = float(lat.mean()) * ms if lat.size else math.nan
            m[f"latency_{name}_p99"] = (
                float(np.percentile(lat, 99.0)) * ms if lat.size else math.nan
            )
        links = self.up + self.down
        m["throughput_mbps"] = sum(ld.bytes for ld in links) * 8 / window / 1e6
        m["packets_per_s"] = sum(ld.packets for ld in links) / window
        m["deliveries_per_s"] = self.messages / window
        m["trigger_rate_hz"] = self.triggers / window
        m["snapshot_rate_hz"] = self.snapshots / window
        m["spread_mean"] = float(np.mean(self.spread)) if self.spread else math.nan
        pe = np.concatenate(self.pos_err) if self.pos_err else np.empty(0)
        m["pos_err_mean"] = float(pe.mean()) if pe.size else math.nan
        return m


def run_baseline(sc: Scenario) -> tuple[dict[str, float], int]:
    """Build and run the baseline; return (metrics, SimPy processes+timeouts+requests)."""
    model = ProcessModel(sc)
    metrics = model.run()
    return metrics, model.sim_events
