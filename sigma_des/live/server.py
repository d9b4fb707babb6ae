"""The live alignment server: trigger source, aligner, behaviour and renderer sampling.

:class:`LiveServer` is the DES's alignment server
(:class:`~sigma_des.events.server.AlignmentServer`: trigger source, aligner,
behaviour, alignment and render ticks, collector) on the live loop's wall clock,
with MQTT as its transport: this module holds only what is live (topics, codecs,
the link shim, the hosts' counters). The rules are the DES's by construction.
Anything malformed or on an unknown topic is counted and dropped.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.config import Scenario
from sigma_des.core.models import SwarmView
from sigma_des.core.rng import RandomStreams
from sigma_des.events.align.base import one_state
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.server import AlignmentServer
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.live.ledger import Ledger
from sigma_des.live.loop import Client, Loop, VirtualLoop
from sigma_des.live.shim import DOWN, ImpairedSender, Impairment
from sigma_des.live.wire import (
    MAX_BUNDLE,
    STATE_BYTES,
    Topics,
    Window,
    WireError,
    check_stats,
    decode_state,
    encode_command,
    encode_rerequest,
    encode_trigger,
)
from sigma_des.metrics.reports import LinkCount
from sigma_des.net.bundlekeys import BundleKeys, first_nodes
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, TRIGGER, rerequest_index

__all__ = ["LiveNet", "LiveServer"]


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

    def links(self) -> list[LinkCount]:
        """Link directions' counts (uplinks first)."""
        keys = sorted(self._links, key=lambda k: (not k.endswith(".up"), _link_order(k)))
        return [LinkCount(k, *self._links[k]) for k in keys]


def _link_order(name: str) -> tuple[int, str]:
    base = name.rsplit(".", 1)[0]
    return (int(base[4:]), "") if base.startswith("host") and base[4:].isdigit() else (10**9, base)


class LiveServer(AlignmentServer, ImpairedSender):
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
        loop: the loop (clock) to run on (None: a real-time :class:`Loop`;
            a :class:`~sigma_des.live.loop.VirtualLoop` runs it on virtual time).
    """

    def __init__(self, sc: Scenario, method: str, client_factory: Any, topics: Topics,
                 qos: int, impair: bool, record: bool = False, bundle: bool = False,
                 loop: Loop | None = None) -> None:
        self.sc = sc
        self.topics = topics
        self.qos = qos
        self.loop = Loop(0.0) if loop is None else loop
        self.loop.wake.lo, self.loop.wake.hi = sc.warmup, sc.duration
        self.host_of = sc.host_of
        self.window = Window.of(sc.duration, sc.f_trig, sc.bides.f_trig_min)
        super().__init__(self.loop, sc.run_spec(), method, make_dynamics(sc),
                         make_behaviour(sc) if sc.commands.enabled else None)
        self.use_hlc = method == "hlc"
        self.net = LiveNet()
        self.ledger = Ledger(sc, "server")
        self.impair = Impairment(sc.net.server_link, sc.net, RandomStreams(sc.seed), sc.hosts,
                                 impair, server=True)
        self._dt = 1.0 / sc.f_trig  # step of the trigger being issued
        self._t_issue = 0.0  # its issue time (the trigger_sent row)
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
        # bundles' draw keys, sent (commands) and received (states), per host's channel
        # (the simulation's rule: sigma_des.net.bundlekeys)
        self._first = first_nodes(sc.host_of)
        self._sent_keys = BundleKeys()
        self._recv_keys = BundleKeys()
        self.running = False
        self.rollbacks = 0
        self.resim_steps = 0
        self.history_misses = 0
        self.wall_seconds = 0.0
        self.got = np.zeros(0, dtype=np.bool_)
        subs = [(topics.up_all, qos)]
        self.client: Client = client_factory(subs, self._on_message)

    # ------------------------------------------------------------ server hooks (MQTT)

    def on_frame(self, k: int, t: float, dt: float) -> None:
        """Trigger ``k`` is issued: remember its step and issue time for the message."""
        self._dt = dt
        self._t_issue = t
        super().on_frame(k, t, dt)

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """One trigger message to every host."""
        t = self.now()
        hl, hc = (stamp.l, stamp.c) if stamp is not None else (-math.inf, 0)
        self._publish(self.topics.trig, encode_trigger(k, t, self._dt, hl, hc), t, TRIGGER,
                      self.n, k)
        # the issue time, as the collector counts the trigger (the publish stamp ``t`` is a
        # few µs later: at a window edge the two could fall on either side of it)
        self.rows.append(("trigger_sent", -1, -1, k, self._t_issue, math.nan, math.nan,
                          math.nan, 0.0))

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: ask ``node`` again for its state of ``frame``."""
        t = self.now()
        index = rerequest_index(frame, retry)
        self._publish(self.topics.rereq(self.host_of[node]),
                      encode_rerequest(node, frame, retry, t), t, REREQUEST, node, index)

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """The tick's commands: one message per node, or (``bundle``) per host."""
        t = self.now()
        ok = nodes.tolist()
        if self.record:
            self.kept["commands"] += [(i, tick, t, cmds[i].tolist()) for i in ok]
        if self.bundle:  # one PUBLISH per host: its nodes' command records back to back,
            # keyed by its place among the host's command bundles of this tick
            per_host: dict[int, list[tuple[int, bytes]]] = {}
            for i in ok:
                per_host.setdefault(self.host_of[i], []).append(
                    (i, encode_command(i, stamp, tick, t, cmds[i])))
            for h, recs in per_host.items():
                key = self._sent_keys.key(h, self._first[h], COMMAND, recs[0][0], tick)
                self._publish(self.topics.cmd(h), b"".join(r for _i, r in recs), t, *key)
            return
        for i in ok:
            payload = encode_command(i, stamp, tick, t, cmds[i])
            self._publish(self.topics.cmd(self.host_of[i]), payload, t, COMMAND, i, tick)

    def snapshot_taken(self, t: float) -> None:
        """``--record``: keep the snapshot."""
        if self.record:
            al = self.aligner
            self.kept["snapshots"].append(
                (t, al.aligned_frame, al.shown_frame.copy(), al.shown_obs.copy()))

    def rendered(self, t: float) -> None:
        """``--record``: keep the render tick's ages."""
        if self.record:
            self.kept["renders"].append((t, t - self.aligner.shown_gen))

    # ------------------------------------------------------------ receiving

    def _on_message(self, topic: str, payload: bytes) -> None:
        self.loop.post(self._arrive, topic, payload, self.loop.now)

    def _arrive(self, topic: str, payload: bytes, t: float) -> None:
        parsed = self.topics.parse_up(topic)
        if parsed is None or parsed[0] >= self.sc.hosts:
            self.unknown_topic += 1
            return
        host, leaf = parsed
        if leaf == "ready":
            self.ready.add(host)
            return
        if leaf == "stats":  # once per host, after stop (the runner clears earlier ones)
            try:
                if self.running or host in self.stats:
                    raise WireError("stats: while running, or a second time")
                self.stats[host] = check_stats(payload, host)
            except WireError:
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
                rec = decode_state(payload[r * size:(r + 1) * size], self.n, self.window)
            except WireError:
                self.rejected += 1
                continue
            if self.host_of[rec[1]] != host or rec[2] > max(self.latest_trigger, 0):
                self.rejected += 1
                continue
            recs.append(rec)
        if not recs:
            return
        if not self.running:
            self.late += len(recs)
            return
        self.ledger.received(recs[0][5], len(topic), len(payload), self.qos)
        # a republished state's draws are keyed by the re-request it answers (its record
        # carries it, as the DES's REPUBLISH); a state's by its frame
        kind, node, _frame, index = recs[0][:4]
        if self.bundle:  # by its place among the host's bundles of that (kind, index)
            kind, node, index = self._recv_keys.key(host, self._first[host], kind, node, index)
        at = self.impair.arrival(t, DOWN, kind, node, index)
        if math.isinf(at):
            return
        for args in recs:
            if at > t:
                self.loop.call_at(at, self._state_at, args)
            else:
                self._state(t, *args)

    def _state_at(self, args: tuple[Any, ...]) -> None:
        self._state(self.now(), *args)

    def _state(self, t: float, kind: int, node: int, frame: int, index: int, t_gen: float,
               t_send: float, hl: float, hc: int, obs: NDArray[np.float64]) -> None:
        if t >= self.sc.duration:
            return
        rep = kind == REPUBLISH
        # each re-request's answer is a message of its own (the DES keys REPUBLISH by it)
        self.collector.delivered(kind, node, index, t_send, t)
        self.rows.append(("state", self.host_of[node], node, frame, t_send, t, self.now(),
                          math.nan, 1.0 if rep else 0.0))
        if self.record:
            self.kept["states"].append((node, frame, t_send, t))
            self.kept["obs"].append(obs.tolist())
        stamp = Stamp(hl, hc) if self.use_hlc else None
        self.aligner.on_states(one_state(t, node, frame, t_gen, obs, stamp))

    # ------------------------------------------------------------ run

    def warm_up(self) -> None:
        """Run the aligner and behaviour once on the initial swarm (compiled kernels load)."""
        st = self.dyn.initial_state(self.n)
        obs = self.dyn.observe(st)
        # a server of its own on a loop never run: its timers and triggers stay unsent
        scratch = AlignmentServer(VirtualLoop(), self.spec, self.method, self.dyn, None).aligner
        for i in range(self.n):
            scratch.on_states(one_state(0.0, i, 0, 0.0, obs[i],
                                         Stamp(0.0, 0) if self.use_hlc else None))
        scratch.align(0.0)
        if self.behaviour is not None:
            view = SwarmView(obs=obs, frame=np.zeros(self.n, dtype=np.int64),
                             valid=np.ones(self.n, dtype=np.bool_), aligned_frame=0)
            self.behaviour.commands(view, self.dyn)

    def start(self, t0: float | None = None) -> None:
        """Set the time origin (monotonic seconds; None: keep the loop's) and schedule
        trigger 0 and the ticks."""
        if t0 is not None:
            self.loop.t0 = t0
        self.running = True
        super().start()

    def finish(self) -> dict[str, Any]:
        """The collector's results, with the hosts' counters folded in."""
        self.running = False
        self.net.add(self.ledger.as_dict())
        for st in self.stats.values():
            self.net.add(st.get("links", {}))
            self.rollbacks += int(st.get("rollbacks", 0))
            self.resim_steps += int(st.get("resim_steps", 0))
            self.history_misses += int(st.get("history_misses", 0))
            self.net.retransmissions += int(st.get("resent", 0))
            self.net.gave_up += int(st.get("gave_up", 0))
        self.net.retransmissions += self.impair.resent
        self.net.gave_up += self.impair.gave_up
        return self.results(rollbacks=self.rollbacks, resim_steps=self.resim_steps,
                            history_misses=self.history_misses, wall_seconds=self.wall_seconds,
                            events=self.loop.handled, net=self.net)
