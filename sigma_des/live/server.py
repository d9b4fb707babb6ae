"""The live alignment server: trigger source, aligner, behaviour and renderer sampling.

:class:`LiveServer` is the engine side of :class:`~sigma_des.events.align.base.ServerContext`
driven by real messages and the wall clock: it runs the simulator's own aligner
(``make_aligner(method, ...)``), behaviour and :class:`~sigma_des.metrics.collector.Collector`
on measured timestamps. Triggers follow the DES rule ``T_k = t0 + (k - k0) / f``
(rebased when BiDES changes the rate; Lock-Step waits for its barrier);
alignment and render ticks run at ``(k + align_phase) / f_align`` and
``(k + render_phase) / f_render``, as in the DES.
Anything malformed or on an unknown topic is counted and dropped.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.base import SwarmView
from sigma_des.config import Scenario
from sigma_des.core.rng import RandomStreams
from sigma_des.events.align import make_aligner
from sigma_des.events.align.base import Aligner, one_state
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.live.ledger import Ledger
from sigma_des.live.loop import Client, Loop
from sigma_des.live.shim import DOWN, ImpairedSender, Impairment
from sigma_des.live.wire import (
    COMMAND,
    MAX_BUNDLE,
    REREQUEST,
    STATE,
    STATE_BYTES,
    TRIGGER,
    Topics,
    WireError,
    decode_state,
    encode_command,
    encode_rerequest,
    encode_trigger,
)
from sigma_des.metrics.collector import Collector
from sigma_des.metrics.reports import NetReport, RunReport

__all__ = ["LiveNet", "LiveServer"]

_REPUBLISH_KIND = 5


class LiveNet:
    """What the collector reads from a network, filled from measured counts."""

    def __init__(self) -> None:
        self._links: dict[str, list[int]] = {}
        self.retransmissions = 0
        self.gave_up = 0
        self.broker_work = math.nan  # the broker's busy time is not observable from outside
        self.broker_max_wait = math.nan

    def add(self, links: dict[str, list[int]]) -> None:
        """Add ``{"<link>.<dir>": [bytes, packets]}`` counts."""
        for k, (b, p) in links.items():
            cur = self._links.setdefault(k, [0, 0])
            cur[0] += int(b)
            cur[1] += int(p)

    def links(self) -> list[SimpleNamespace]:
        """Link directions with ``name``, ``bytes`` and ``packets`` (uplinks first)."""
        keys = sorted(self._links, key=lambda k: (not k.endswith(".up"), _link_order(k)))
        return [SimpleNamespace(name=k, bytes=v[0], packets=v[1])
                for k, v in ((k, self._links[k]) for k in keys)]


def _link_order(name: str) -> tuple[int, str]:
    base = name.rsplit(".", 1)[0]
    return (int(base[4:]), "") if base.startswith("host") and base[4:].isdigit() else (10**9, base)


class _Scratch:
    """A do-nothing server context for :meth:`LiveServer.warm_up`."""

    def __init__(self, f_trig: float) -> None:
        self.latest_trigger = 0
        self.f_trig = f_trig

    def now(self) -> float:
        return 0.0

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        pass

    def set_rate(self, f_trig: float) -> None:
        pass

    def barrier_done(self, frame: int) -> None:
        pass

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        pass


class LiveServer(ImpairedSender):
    """One method's alignment server over MQTT.

    Args:
        sc: the scenario.
        method: alignment method.
        addr_client: a factory ``(subscriptions, on_message) -> Client``.
        topics: the run's topics.
        qos: MQTT QoS of every message.
        impair: apply the server link's impairments.
        record: keep states with their pose, snapshots and render samples in
            :attr:`kept` (for ``live --record``).
        bundle: send each host's commands of one tick as one PUBLISH.
    """

    def __init__(self, sc: Scenario, method: str, client_factory: Any, topics: Topics,
                 qos: int, impair: bool, record: bool = False, bundle: bool = False) -> None:
        self.sc = sc
        self.method = method
        self.n = n = sc.nodes
        self.topics = topics
        self.qos = qos
        self.loop = Loop(0.0)
        self.host_of = sc.host_of
        self.dyn = make_dynamics(sc)
        self.behaviour = make_behaviour(sc) if sc.commands.enabled else None
        self.f_trig = sc.f_trig
        self.latest_trigger = -1
        self.trig_time: dict[int, float] = {}
        self._base: tuple[float, int, float] = (0.0, 0, sc.f_trig)
        self.use_hlc = method == "hlc"
        self.server_hlc = HLC()
        self.net = LiveNet()
        self.ledger = Ledger(sc, "server")
        self.aligner: Aligner = make_aligner(method, n, self, sc.align_params())
        self.collector = Collector(sc.collector_spec(), method)
        self.impair = Impairment(sc.net.server_link, sc.net, RandomStreams(sc.seed), sc.hosts,
                                 impair)
        self.align_tick = 0
        self.render_tick = 0
        self.record = record
        self.bundle = bundle
        self.kept: dict[str, list[Any]] = {"states": [], "obs": [], "snapshots": [],
                                           "renders": [], "commands": []}
        self.rows: list[tuple[Any, ...]] = []
        self.ready: set[int] = set()
        self.stats: dict[int, dict[str, Any]] = {}
        self.rejected = 0
        self.unknown_topic = 0
        self.late = 0
        self.running = False
        self.rollbacks = 0
        self.resim_steps = 0
        self.history_misses = 0
        self.wall_seconds = 0.0
        self.kernel = SimpleNamespace(events=0)
        self.got = np.zeros(0, dtype=np.bool_)
        subs = [(topics.up_all, qos)]
        self.client: Client = client_factory(subs, self._on_message)

    # ------------------------------------------------------------ ServerContext

    def now(self) -> float:
        """Seconds since the first trigger."""
        return self.loop.now()

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        """Server-side timer."""
        self.loop.call_at(t, fn, *args)

    def set_rate(self, f_trig: float) -> None:
        """BiDES: change the trigger rate from the next trigger on."""
        self.f_trig = f_trig
        self.collector.rate_change(self.now(), f_trig)

    def barrier_done(self, frame: int) -> None:
        """Lock-Step: trigger ``frame + 1`` no sooner than ``1/f_trig`` after ``frame``.

        As in the DES, the earliest time is on the grid ``t0 + (k - k0) / f`` (never a
        running sum); a barrier that completes later triggers at once and restarts the
        grid there.
        """
        k = frame + 1
        t0, k0, f = self._base
        if self.f_trig != f:
            t0, k0, f = self._base = (self.trig_time[frame], frame, self.f_trig)
        t = t0 + (k - k0) / f
        now = self.now()
        if t < now:
            t = now
            self._base = (now, k, f)
        self.loop.call_at(t, self._issue)

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: ask ``node`` again for its state of ``frame``."""
        t = self.now()
        self._publish(self.topics.rereq(self.host_of[node]),
                      encode_rerequest(node, frame, retry, t), t, REREQUEST, node,
                      frame * 64 + min(retry, 63))

    # ------------------------------------------------------------ sending

    def _issue(self) -> None:
        t = self.now()
        if t >= self.sc.duration:
            return
        k = self.latest_trigger + 1
        dt = 1.0 / self.f_trig
        self.trig_time[k] = t
        self.trig_time.pop(k - self.sc.history_frames, None)
        self.latest_trigger = k
        self.collector.trigger(t, k, dt)
        self.aligner.on_trigger(k, t)
        stamp = self.server_hlc.send(t) if self.use_hlc else Stamp(-math.inf, 0)
        self._publish(self.topics.trig, encode_trigger(k, t, dt, stamp.l, stamp.c), t, TRIGGER,
                      self.n, k)
        self.rows.append(("trigger_sent", -1, -1, k, t, math.nan, math.nan, math.nan, 0.0))
        if self.method != "lockstep":
            if self.f_trig != self._base[2]:
                self._base = (t, k, self.f_trig)
            t0, k0, f = self._base
            self.loop.call_at(t0 + (k + 1 - k0) / f, self._issue)

    # ------------------------------------------------------------ receiving

    def _on_message(self, topic: str, payload: bytes) -> None:
        self.loop.post(self._arrive, topic, payload, self.loop.now())

    def _arrive(self, topic: str, payload: bytes, t: float) -> None:
        parsed = self.topics.parse_up(topic)
        if parsed is None or parsed[0] >= self.sc.hosts:
            self.unknown_topic += 1
            return
        host, leaf = parsed
        if leaf == "ready":
            self.ready.add(host)
            return
        if leaf == "stats":
            try:
                self.stats[host] = json.loads(payload)
            except ValueError:
                self.rejected += 1
            return
        size = STATE_BYTES
        count = len(payload) // size
        if len(payload) % size or not 1 <= count <= MAX_BUNDLE:
            self.rejected += 1  # not a whole number of states (or too many): drop it all
            return
        recs = []
        for r in range(count):
            try:
                rec = decode_state(payload[r * size:(r + 1) * size], self.n)
            except WireError:
                self.rejected += 1
                continue
            if self.host_of[rec[1]] != host:
                self.rejected += 1
                continue
            recs.append(rec)
        if not recs:
            return
        if not self.running:
            self.late += len(recs)
            return
        self.ledger.received(recs[0][4], len(topic), len(payload), self.qos)
        d = self.impair.delay(t, DOWN, STATE, recs[0][1], recs[0][2])
        if math.isinf(d):
            return
        for args in recs:
            if d > 0:
                self.loop.call_at(t + d, self._state_at, args)
            else:
                self._state(t, *args)

    def _state_at(self, args: tuple[Any, ...]) -> None:
        self._state(self.now(), *args)

    def _state(self, t: float, kind: int, node: int, frame: int, t_gen: float, t_send: float,
               hl: float, hc: int, obs: NDArray[np.float64]) -> None:
        if t >= self.sc.duration:
            return
        rep = kind == _REPUBLISH_KIND
        self.collector.delivered(_REPUBLISH_KIND if rep else STATE, node, frame, t_send, t)
        self.rows.append(("state", self.host_of[node], node, frame, t_send, t, self.now(),
                          math.nan, 1.0 if rep else 0.0))
        if self.record:
            self.kept["states"].append((node, frame, t_send, t))
            self.kept["obs"].append(obs.tolist())
        stamp = Stamp(hl, hc) if self.use_hlc else None
        self.aligner.on_states(one_state(t, node, frame, t_gen, obs, stamp))

    # ------------------------------------------------------------ ticks

    def _align(self) -> None:
        t = self.now()
        if t >= self.sc.duration:
            return
        al = self.aligner
        al.align(t)
        self.collector.shown(t, al.shown_gen)
        if al.new_snapshot:
            self.collector.snapshot(t)
            if self.record:
                self.kept["snapshots"].append(
                    (t, al.aligned_frame, al.shown_frame.copy(), al.shown_obs.copy())
                )
        if self.behaviour is not None and self.align_tick % self.sc.commands.every == 0:
            self._send_commands(t)
        self.align_tick += 1
        self.loop.call_at(self._align_time(self.align_tick), self._align)

    def _send_commands(self, t: float) -> None:
        al = self.aligner
        valid = ~np.isnan(al.shown_gen)
        if not valid.any():
            return
        assert self.behaviour is not None
        view = SwarmView(obs=al.shown_obs, frame=al.shown_frame, valid=valid,
                         aligned_frame=al.aligned_frame)
        cmds = self.behaviour.commands(view, self.dyn)
        ok = np.flatnonzero(~np.isnan(cmds).all(axis=1))
        tick = self.align_tick
        if self.record:
            self.kept["commands"] += [(i, tick, t, cmds[i].tolist()) for i in ok.tolist()]
        if self.bundle:  # one PUBLISH per host: its nodes' command records back to back
            per_host: dict[int, list[bytes]] = {}
            for i in ok.tolist():
                per_host.setdefault(self.host_of[i], []).append(
                    encode_command(i, al.aligned_frame, tick, t, cmds[i]))
            for h, recs in per_host.items():
                self._publish(self.topics.cmd(h), b"".join(recs), t, COMMAND, h, tick)
            return
        for i in ok.tolist():
            payload = encode_command(i, al.aligned_frame, tick, t, cmds[i])
            self._publish(self.topics.cmd(self.host_of[i]), payload, t, COMMAND, i, tick)

    def _render(self) -> None:
        t = self.now()
        if t >= self.sc.duration:
            return
        al = self.aligner
        self.collector.render(t, al.shown_gen, al.shown_frame, al.shown_obs, al.flag, None,
                              self.f_trig, self.latest_trigger, al.aligned_frame)
        if self.record:
            self.kept["renders"].append((t, t - al.shown_gen))
        self.render_tick += 1
        self.loop.call_at(self._render_time(self.render_tick), self._render)

    # ------------------------------------------------------------ run

    def warm_up(self) -> None:
        """Run the aligner and behaviour once on the initial swarm (compiled kernels load)."""
        sc = self.sc
        st = self.dyn.initial_state(self.n)
        obs = self.dyn.observe(st)
        scratch = make_aligner(self.method, self.n, _Scratch(sc.f_trig), sc.align_params())
        for i in range(self.n):
            scratch.on_states(one_state(0.0, i, 0, 0.0, obs[i],
                                         Stamp(0.0, 0) if self.use_hlc else None))
        scratch.align(0.0)
        if self.behaviour is not None:
            view = SwarmView(obs=obs, frame=np.zeros(self.n, dtype=np.int64),
                             valid=np.ones(self.n, dtype=np.bool_), aligned_frame=0)
            self.behaviour.commands(view, self.dyn)

    def start(self, t0: float) -> None:
        """Set the time origin (monotonic seconds) and schedule trigger 0 and the ticks."""
        self.loop.t0 = t0
        self.running = True
        self.loop.call_at(0.0, self._issue)
        self.loop.call_at(self._align_time(0), self._align)
        self.loop.call_at(self._render_time(0), self._render)

    def _align_time(self, j: int) -> float:
        """Alignment tick ``j`` at ``(j + align_phase) / f_align`` (the DES's tick grid)."""
        return (j + self.sc.align_phase) / self.sc.f_align

    def _render_time(self, j: int) -> float:
        """Render tick ``j`` at ``(j + render_phase) / f_render``."""
        return (j + self.sc.render_phase) / self.sc.f_render

    def finish(self) -> dict[str, Any]:
        """The collector's results, with the hosts' counters folded in."""
        self.running = False
        self.net.add(self.ledger.as_dict())
        for st in self.stats.values():
            self.net.add(st.get("links", {}))
            self.rollbacks += int(st.get("rollbacks", 0))
            self.resim_steps += int(st.get("resim_steps", 0))
            self.history_misses += int(st.get("history_misses", 0))
            self.net.retransmissions += int(st.get("lost", 0))
            self.net.gave_up += int(st.get("gave_up", 0))
        self.net.retransmissions += self.impair.lost
        self.net.gave_up += self.impair.gave_up
        self.kernel.events = self.loop.handled
        run = RunReport(f_trig=self.f_trig, rollbacks=self.rollbacks, resim_steps=self.resim_steps,
                        history_misses=self.history_misses, wall_seconds=self.wall_seconds,
                        events=self.kernel.events)
        return self.collector.finish(run, self.aligner.report(), NetReport.of(self.net))
