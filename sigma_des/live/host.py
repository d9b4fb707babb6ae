"""A live physics host: one OS process, one MQTT client, the nodes placed on it.

On every trigger the host steps all its nodes' aircraft to the trigger's frame with
the scenario's dynamics model (catching up over lost triggers), for real, in the DES's
physics truth of those nodes (:class:`~sigma_des.events.truth.SwarmTruth`); then
its nodes follow the DES's node rules (:class:`~sigma_des.events.node.NodeRules`,
here :class:`HostNodes` on the live loop): each job's cost is the DES's
:func:`~sigma_des.events.jobs.job_cost` (the drawn ``compute.step_time``, when
``step_delay`` is on) on ``cores_per_host`` FCFS cores, triggers coalesce, a
re-request is answered by republishing, commands apply at frame boundaries and
BiDES time warp rolls a node back, crash and slow faults act as in the DES. This
module holds only what is live: MQTT, codecs, the real physics stepping. Run as
``python -m sigma_des.live.host CONFIG.json``; the runner writes that file.
"""

from __future__ import annotations

import gc
import json
import math
import os
import sys
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.config import Scenario
from sigma_des.core.rng import RandomStreams
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.jobs import step_draws
from sigma_des.events.node import NodeRules, Published
from sigma_des.events.truth import FrameTrack, SwarmTruth
from sigma_des.factory import make_dynamics
from sigma_des.live.broker import BrokerAddress
from sigma_des.live.clocksync import PING, PONG, SyncTopics, host_clock, now_fn
from sigma_des.live.ledger import Ledger
from sigma_des.live.loop import Client, Loop
from sigma_des.live.shim import DOWN, ImpairedSender, Impairment
from sigma_des.live.wire import (
    MAX_BUNDLE,
    Topics,
    Window,
    WireError,
    command_bytes,
    decode_command,
    decode_control,
    decode_rerequest,
    decode_trigger,
    encode_state,
)
from sigma_des.loading import from_dict
from sigma_des.net.bundlekeys import BundleKeys
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER, rerequest_index

__all__ = ["ClockLoop", "Host", "HostNodes", "main"]


class ClockLoop(Loop):
    """A :class:`Loop` on another clock than ``time.monotonic()`` (a host whose clock
    a test sets off: :func:`~sigma_des.live.clocksync.host_clock`)."""

    def __init__(self, t0: float, mono: Any) -> None:
        super().__init__(t0)
        self._mono = mono

    @property
    def now(self) -> float:
        """Seconds since the run's start on this host's clock."""
        return float(self._mono()) - self.t0


class HostNodes(NodeRules):
    """The nodes of one live host: the DES's node rules, publishing over MQTT.

    Args:
        host: the host process (its truth, its transport).
        step_delay: jobs take their drawn compute time (False: no time).
        **rules: the :class:`~sigma_des.events.node.NodeRules` arguments.

    Attributes:
        trig_t: when each node accepted its newest trigger (for the message rows).
        job_s: the cost of each node's newest job.
    """

    def __init__(self, host: Host, step_delay: bool, **rules: Any) -> None:
        super().__init__(truth=host.truth, **rules)
        self.host = host
        self.step_delay = step_delay
        self.trig_t = [0.0] * len(self.ids)
        self.job_s = [0.0] * len(self.ids)

    def cost(self, i: int, target: int, now: float) -> float:
        """The DES's job cost (no time without ``step_delay``)."""
        c = super().cost(i, target, now) if self.step_delay else 0.0
        self.job_s[i] = c
        return c

    def on_trigger(self, i: int, k: int) -> None:
        """The DES's rule; the time a newer trigger is accepted is noted for the rows."""
        if k > self.req[i]:
            self.trig_t[i] = self.clock.now
        super().on_trigger(i, k)

    def publish_state(self, i: int, payload: Published) -> None:
        """Send the state (and note the ``state_pub`` row)."""
        frame, t, _obs, _stamp = payload
        self.host.send_state(i, payload, t, False)
        self.host.rows.append(("state_pub", self.host.h, self.ids[i], frame, t, math.nan,
                               self.trig_t[i], self.job_s[i], 0.0))

    def republish(self, i: int, index: int, payload: Published) -> None:
        """Send the last state again."""
        self.host.send_state(i, payload, self.clock.now, True, index)


class Host(ImpairedSender):
    """The nodes of one physics host, driven by MQTT messages.

    Args:
        sc: the scenario.
        method: the alignment method of this run.
        host: this host's index.
        cfg: live options (``qos``, ``impair``, ``step_delay``, ``max_inflight``).
        topics: the run's topics.
        addr: the broker.
        t0: the run's time origin (monotonic seconds).
        client_factory: ``(subscriptions, on_message) -> Client`` (None: a paho
            client of ``addr``).
        loop: the loop to run on (None: a real-time :class:`Loop` from ``t0``).
    """

    def __init__(self, sc: Scenario, method: str, host: int, cfg: dict[str, Any],
                 topics: Topics, addr: BrokerAddress, t0: float,
                 client_factory: Any = None, loop: Loop | None = None) -> None:
        self.sc = sc
        self.method = method
        self.h = host
        self.qos = int(cfg["qos"])
        self.bundle = bool(cfg.get("bundle", False))
        # --bundle: this turn's records (payload and own draw key) and the bundles' keys
        # as sent and as received (the simulation's rule: sigma_des.net.bundlekeys)
        self._pending: list[tuple[bytes, int, int, int]] = []
        self._sent_keys = BundleKeys()
        self._recv_keys = BundleKeys()
        self.topics = topics
        self.window = Window.of(sc.duration, sc.f_trig, sc.bides.f_trig_min)
        skew = host_clock()
        self.mono = now_fn(*skew)
        if loop is None:
            loop = ClockLoop(t0, self.mono) if skew != (0.0, 0.0) else Loop(t0)
        self.loop = loop
        self.loop.wake.lo, self.loop.wake.hi = sc.warmup, sc.duration
        n = sc.nodes
        self.nodes = np.flatnonzero(np.asarray(sc.host_of) == host).astype(np.int64)
        self.local = {int(g): j for j, g in enumerate(self.nodes)}
        m = self.m = self.nodes.size
        self.dyn = make_dynamics(sc)
        self.cmd = self.dyn.default_command(self.dyn.initial_state(n))[self.nodes].copy()
        self.warp = method == "bides" and sc.bides.time_warp
        # the DES's truth of this host's nodes: every frame's true positions logged
        self.track = FrameTrack(m)
        self.truth = SwarmTruth(self.dyn, n, sc.history_frames, sc.fidelity.log_rate,
                                self.warp, self.nodes, self.track)
        streams = RandomStreams(sc.seed)
        self.use_hlc = method == "hlc"
        self.jobs = HostNodes(
            self,
            bool(cfg["step_delay"]),
            clock=self.loop,
            host_of=[0] * m,
            hosts=1,
            cores_per_host=sc.cores_per_host,
            step_time=step_draws(sc.compute, streams, sc.host_of),
            faults=sc.faults,
            clocks=NodeClocks(sc.clocks, streams.stream("clocks"), n),
            hlc=self.use_hlc,
            warp=sc.bides.theta_warp if self.warp else None,
            cmd=self.cmd,
            ids=self.nodes.tolist(),
        )
        self.impair = Impairment(sc.net.host_link, sc.net, streams, host, bool(cfg["impair"]))
        self.ledger = Ledger(sc, f"host{host}")
        self.rows: list[tuple[Any, ...]] = []
        self.step_real_s = 0.0
        self.steps = 0
        self.rejected = 0
        self.stop_requested = False
        self.started = False
        subs = [(topics.trig, self.qos), (topics.host_down(host), self.qos), (topics.ctl, 1)]
        # across machines (--scheduler): clock exchanges and a go on this host's own clock
        self.sync = SyncTopics(topics.run) if cfg.get("sync") else None
        if self.sync is not None:  # not its own pongs: they are no forged traffic
            subs += [(self.sync.ping(host), 1), (self.sync.go(host), 1)]
        if client_factory is None:
            self.client = Client(addr, f"{topics.run}-h{host}", subs, self._on_message,
                                 int(cfg["max_inflight"]))
        else:
            self.client = client_factory(subs, self._on_message)

    # ------------------------------------------------------------ messages

    def _on_message(self, topic: str, payload: bytes) -> None:
        if self.sync is not None and topic.startswith(self.sync.base):
            self._sync(topic, payload)
            return
        self.loop.post(self._arrive, topic, payload, self.loop.now)

    def _sync(self, topic: str, payload: bytes) -> None:
        """A clock ping is answered at once from paho's thread (receipt and reply stamped
        on this host's clock); ``go`` carries the origin on this host's clock."""
        assert self.sync is not None
        if topic == self.sync.ping(self.h) and len(payload) == PING.size:
            t2 = self.mono()
            seq, t1 = PING.unpack(payload)
            self.client.publish(self.sync.pong(self.h), PONG.pack(seq, t1, t2, self.mono()), 0)
        elif topic == self.sync.go(self.h):
            self.loop.post(self._arrive, self.topics.ctl, payload, self.loop.now)
        else:
            self.loop.post(self._reject)

    def _reject(self) -> None:
        self.rejected += 1

    def _arrive(self, topic: str, payload: bytes, t: float) -> None:
        tp = self.topics
        try:
            if topic == tp.trig:
                frame, t_send, dt, hl, hc = decode_trigger(payload, self.window, t)
                # the DES keys a trigger's delivery to a host client by its first node
                self._deliver(t, TRIGGER, int(self.nodes[0]), frame, t_send, len(topic),
                              len(payload), self._on_trigger, frame, t_send, dt, hl, hc)
            elif topic == tp.cmd(self.h):
                self._commands(t, topic, payload)
            elif topic == tp.rereq(self.h):
                node, frame, retry, t_send = decode_rerequest(payload, self.window)
                j = self._local_index(node)
                index = rerequest_index(frame, retry)
                self._deliver(t, REREQUEST, node, index, t_send, len(topic), len(payload),
                              self._on_rerequest, j, frame, index)
            elif topic == tp.ctl:
                self._control(payload)
            else:
                self.rejected += 1
        except WireError:
            self.rejected += 1

    def _commands(self, t: float, topic: str, payload: bytes) -> None:
        """One command, or (``--bundle``) a whole number of same-size command records."""
        width = self.cmd.shape[1]
        size = command_bytes(width)
        if len(payload) % size or len(payload) // size > MAX_BUNDLE:
            raise WireError(f"command: {len(payload)} bytes is not a multiple of {size}")
        recs = []
        for r in range(len(payload) // size):
            node, stamp, tick, t_send, vals = decode_command(payload[r * size:(r + 1) * size],
                                                             width, self.window)
            recs.append((self._local_index(node), stamp, tick, t_send, vals))
        if not recs:
            raise WireError("command: empty")
        kind, node, tick = COMMAND, int(self.nodes[recs[0][0]]), int(recs[0][2])
        if self.bundle:  # keyed by its place among this host's command bundles of the tick
            kind, node, tick = self._recv_keys.key(self.h, int(self.nodes[0]), kind, node, tick)
        self._deliver(t, kind, node, tick, recs[0][3], len(topic), len(payload),
                      self._on_commands, recs)

    def _on_commands(self, t: float, recs: list[tuple[Any, ...]]) -> None:
        for j, stamp, tick, t_send, row in recs:
            self.rows.append(("command", self.h, int(self.nodes[j]), tick, t_send, t, math.nan,
                              math.nan, 0.0))
            self.jobs.receive_command(j, stamp, row, t)

    def _on_rerequest(self, t: float, j: int, frame: int, index: int) -> None:
        self.jobs.receive_rerequest(j, frame, index, t)

    def _control(self, payload: bytes) -> None:
        """``go:<t0>`` sets the run's time origin (monotonic seconds), once; ``stop``
        ends the run."""
        what, t0 = decode_control(payload, self.mono())
        if what == "stop":
            self.stop_requested = True
            self.loop.stop()
        elif not self.started:
            self.loop.t0 = t0
            self.started = True
        elif t0 != self.loop.t0:  # a QoS 1 duplicate repeats it; anything else is forged
            raise WireError("control: a second go with another t0")

    def _local_index(self, node: int) -> int:
        j = self.local.get(node)
        if j is None:
            raise WireError(f"node {node} is not on host {self.h}")
        return j

    def _deliver(self, t: float, kind: int, subject: int, index: int, t_send: float,
                 topic_len: int, size: int, fn: Any, *args: Any) -> None:
        self.ledger.received(t_send, topic_len, size, self.qos)
        at = self.impair.arrival(t, DOWN, kind, subject, index)
        if math.isinf(at):
            return
        if at > t:
            self.loop.call_at(at, self._release, fn, args)
        else:
            fn(t, *args)

    def _release(self, fn: Any, args: tuple[Any, ...]) -> None:
        fn(self.loop.now, *args)

    # ------------------------------------------------------------ physics

    def _on_trigger(self, t: float, k: int, t_send: float, dt: float, hl: float,
                    hc: int) -> None:
        self.rows.append(("trigger", self.h, -1, k, t_send, t, math.nan, math.nan, 0.0))
        truth = self.truth
        if k > truth.latest:
            w0 = time.perf_counter()
            self.steps += k - truth.latest
            for f in range(truth.latest + 1, k + 1):  # catching up over lost triggers
                truth.step_frame(f, dt, self.cmd, None)
            self.step_real_s += time.perf_counter() - w0
        stamp = Stamp(hl, hc) if self.use_hlc else None
        for j in range(self.m):
            self.jobs.receive_trigger(j, k, stamp, t)

    @property
    def frame(self) -> int:
        """The newest frame stepped (-1 before the first)."""
        return self.truth.latest

    def track_arrays(self) -> dict[str, NDArray[Any]]:
        """Every frame's true positions, in frame order: the run is over (the truth's
        ring is released)."""
        self.truth.release()
        fr, t, pos = self.track.arrays()
        return {"track_frames": fr, "track_t": t, "track_pos": pos, "nodes": self.nodes}

    def send_state(self, j: int, payload: Published, t: float, republish: bool,
                   index: int = -1) -> None:
        """Publish node ``j``'s state ``payload`` at ``t`` (one message or, with
        ``bundle``, a record of this loop turn's message); a republish answers re-request
        ``index`` (its draws are keyed by it, as the DES's REPUBLISH)."""
        frame, t_gen, obs, stamp = payload
        hl, hc = (stamp.l, stamp.c) if stamp is not None else (-math.inf, 0)
        node = int(self.nodes[j])
        msg = encode_state(node, frame, t_gen, t, hl, hc, obs, republish, index)
        kind, key = (REPUBLISH, index) if republish else (STATE, frame)
        if not self.bundle:
            self._publish(self.topics.state(self.h), msg, t, kind, node, key)
            return
        if not self._pending:
            self.loop.call_at(t, self._flush)  # after the current handler, before the inbox
        self._pending.append((msg, kind, node, key))

    def _flush(self) -> None:
        """``--bundle``: publish the states of this loop turn as one message, keyed by its
        place among this host's bundles of its first record's ``(kind, index)``."""
        pend, self._pending = self._pending, []
        if pend:
            t = self.loop.now
            _p, kind, node, index = pend[0]
            key = self._sent_keys.key(self.h, int(self.nodes[0]), kind, node, index)
            self._publish(self.topics.state(self.h), b"".join(p[0] for p in pend), t, *key)

    # ------------------------------------------------------------ run

    def announce(self) -> None:
        """Publish ``ready`` every 0.2 s until ``go`` (the server may subscribe after us)."""
        if self.started:
            return
        self.client.publish(self.topics.ready(self.h), b"1", 1)
        self.loop.call_at(self.loop.now + 0.2, self.announce)

    def warm_up(self) -> None:
        """Call every compiled kernel once (numba loads its cache lazily on first call)."""
        dt = 1.0 / self.sc.f_trig
        state = self.truth.state
        s = self.dyn.step(state.copy(), self.cmd, dt, 0, self.nodes)
        self.dyn.observe(s)
        if self.m:
            one = self.dyn.step(state[:1].copy(), self.cmd[:1], dt, 0, self.nodes[:1])
            self.dyn.observe(one)

    def stats(self) -> dict[str, Any]:
        """End-of-run counters sent to the server."""
        return {
            "host": self.h,
            "links": self.ledger.as_dict(),
            "rollbacks": self.truth.rollbacks,
            "resim_steps": self.truth.resim_steps,
            "history_misses": self.jobs.history_misses,
            "rejected": self.rejected,
            "resent": self.impair.resent,
            "gave_up": self.impair.gave_up,
            "connects": self.client.connects,
            "disconnects": self.client.disconnects,
            "steps": self.steps,
            "step_real_s": self.step_real_s,
            "wake": self.loop.wake.as_dict(),
        }


def main(argv: list[str] | None = None) -> int:
    """Entry point of a host process: ``python -m sigma_des.live.host CONFIG.json``.

    The process serves the runs listed in the config (one per method) one after
    the other: for each, a fresh :class:`Host` on the run's topics announces itself
    ready, runs until ``stop`` (bounded by duration + ``linger`` s), reports its
    counters and writes its rows.
    """
    args = sys.argv[1:] if argv is None else argv
    with open(args[0]) as f:
        cfg = json.loads(f.read())
    if not os.environ.get("SIGMA_DES_LIVE_KEEP"):
        os.unlink(args[0])  # it holds the broker's credentials: read once, not left on disk
    sc = from_dict(Scenario, cfg["scenario"])
    addr = BrokerAddress(**cfg["broker"])
    h = int(cfg["host"])
    for i, (method, run) in enumerate(cfg["runs"]):
        topics = Topics(run)
        host = Host(sc, method, h, cfg, topics, addr, now_fn(*host_clock())())
        if i == 0:
            host.warm_up()
        host.client.start(timeout=10.0)
        gc.collect()  # what earlier runs left, before the clock matters (the loop pauses it)
        host.announce()
        host.loop.run(until=sc.duration + float(cfg.get("linger", 120.0)))
        host.client.publish(topics.stats(h), json.dumps(host.stats()).encode(), 1)
        _write_rows(cfg["rows_path"].format(run=run), host.rows, host.track_arrays())
        time.sleep(0.1)  # let paho flush the stats message
        host.client.stop()
    return 0


def _write_rows(path: str, rows: list[tuple[Any, ...]], track: dict[str, NDArray[Any]]) -> None:
    arr = np.array([r[1:] for r in rows], dtype=np.float64).reshape(-1, 8)
    kinds = np.array([r[0] for r in rows], dtype="U10")
    tmp = path + ".part.npz"
    np.savez(tmp, kinds=kinds, values=arr, track_frames=track["track_frames"],
             track_t=track["track_t"], track_pos=track["track_pos"], nodes=track["nodes"])
    os.replace(tmp, path)  # the runner waits for the file: it must appear complete


if __name__ == "__main__":
    raise SystemExit(main())
