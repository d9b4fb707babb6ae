"""MQTT clients over the modelled links, through the broker (docs/concepts/model.md,
"Network").

Links and transports (FIFO serialization, latency, loss, in-order streams) are
in :mod:`sigma_des.net.links`, the broker's FIFO service in
:mod:`sigma_des.net.broker`; this module is the MQTT side: publish, QoS 1
PUBACKs and resends, receive. QoS 1 over ``datagram`` resends with DUP after
``qos1_timeout`` when no PUBACK came, so duplicates can reach receivers; over
``stream`` the PUBACKs are counted traffic. All downlink traffic leaves the
broker in service order, so downlink FIFO reservations are made when the broker
serves.

With a CPU stage (:mod:`sigma_des.net.cpu`) a client's publish is a burst of its
process's demand (the PUBLISH leaves at its end) and every copy it receives is a burst
at its arrival (the latency ends at the burst's start; with a network thread, at that
thread's burst's end); what is charged where: docs/concepts/deployment.md. With per-host
clients (``deployment.clients = "host"``) the MQTT clients are the physics hosts (client
id: the host's first node) and the server: a node's state leaves through its host's
client, and what a host client receives is handed to its nodes (a trigger, the only
broadcast, to each in node order; a message about node ``i`` to ``i``). With ``bundle``
a host client's state publishes of one loop turn are one PUBLISH, and so are the
server's commands of one turn to one host (:mod:`sigma_des.net.bundling`).

This module knows nothing of alignment methods or aircraft: a delivered message
is handed to the ``deliver`` callback given at construction.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.broker import Broker
from sigma_des.net.bundling import Bundle, Bundler
from sigma_des.net.cpu import Cpu, CpuReport
from sigma_des.net.kinds import ACK, COMMAND, TRIGGER
from sigma_des.net.links import Links
from sigma_des.net.message import Msg
from sigma_des.net.spec import NetSetup
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, payload_bytes, publish_bytes

__all__ = ["Bundle", "Network"]

#: called with every message that reaches its receiver (duplicates included)
Deliver = Callable[[Msg], None]


class Network(Links):
    """Links, transport, QoS and broker for ``n`` nodes plus the server.

    Args:
        kernel: the SimPy glue.
        setup: the net's specs, topology, metrics window and link faults.
        streams: root random streams.
        deliver: ``deliver(m)`` is called with the :class:`~sigma_des.net.message.Msg`
            of every PUBLISH at its application-level arrival at a client
            (duplicates included; ``m.client`` is the receiver).
    """

    def __init__(
        self, kernel: Kernel, setup: NetSetup, streams: RandomStreams, deliver: Deliver
    ) -> None:
        super().__init__(kernel, setup, streams)
        self.deliver = deliver
        net = setup.net
        self.qos1 = net.qos == 1
        self.timeout = net.qos1_timeout
        self._topic = net.topic_bytes
        dep = setup.deployment
        topo = setup.topology
        self.cpu = Cpu(dep, topo.hosts, self.warmup, self.end) if dep.cpu else None
        cpu = self.cpu
        self.broker = Broker(setup.broker, streams, self.n + 1, self.warmup, self.end,
                             cpu.broker if cpu is not None else None)
        self._wire_cache: dict[int, int] = {}
        self._ack_b = frame_bytes(PUBACK_BYTES, net.tcpip_bytes, net.ethernet_bytes)
        # each client's process and demand (None: no burst, as without a CPU stage)
        self._demand = [dep.host_demand] * self.n + [dep.server_demand]
        self._record = [dep.host_record] * self.n + [dep.server_record]
        self._proc = [None] * (self.n + 1) if cpu is None else [
            p if d > 0.0 else None
            for p, d in zip([*(cpu.hosts[h] for h in topo.host_of), cpu.server], self._demand,
                            strict=True)
        ]
        self._tick = dep.server_tick if cpu is not None else 0.0
        # per-host clients: host h's client is its first node; members: its nodes in order
        self.host_clients = dep.clients == "host"
        self.bundle = dep.bundle
        first: dict[int, int] = {}
        self.members: dict[int, list[int]] = {}
        for i, h in enumerate(topo.host_of):
            first.setdefault(h, i)
            self.members.setdefault(first[h], []).append(i)
        self.client_of = ([first[h] for h in topo.host_of] if self.host_clients
                          else list(range(self.n))) + [self.server]
        # a drop fault naming a bundle's first record drops that bundle
        self._bundler = Bundler(self._proc, self.server, self.client_of,
                                self.forced_drops if self.bundle else frozenset())
        # publishes whose burst ended while their process was busy, in burst order, and
        # the latest time the first of them leaves (lock_switch after its burst's end)
        self._lock_switch = dep.lock_switch if cpu is not None else 0.0
        self._outbox: dict[str, tuple[float, list[Msg]]] = {}
        self._inbox: dict[str, float] = {}
        # the application receives through a burst or a hand-over (else: deliver at once)
        self._app_stage = self.host_clients or any(p is not None for p in self._proc)

    # ------------------------------------------------------------ sizes

    def wire_bytes(self, payload_bits: int) -> int:
        """Wire bytes of one PUBLISH carrying ``payload_bits`` at the scenario's QoS."""
        b = self._wire_cache.get(payload_bits)
        if b is None:
            b = self._wire_cache[payload_bits] = frame_bytes(
                publish_bytes(self._topic, payload_bytes(payload_bits), 1 if self.qos1 else 0),
                self.setup.net.tcpip_bytes,
                self.setup.net.ethernet_bytes,
            )
        return b

    @property
    def ack_bytes(self) -> int:
        """Wire bytes of one PUBACK."""
        return self._ack_b

    @property
    def broker_work(self) -> float:
        """Broker service seconds inside the metrics window."""
        return self.broker.work

    @property
    def broker_max_wait(self) -> float:
        """Longest wait of a PUBLISH at the broker in the metrics window (s)."""
        return self.broker.max_wait

    def cpu_report(self) -> CpuReport | None:
        """The CPU stage's counters (None: the deployment has no CPU stage)."""
        return self.cpu.report() if self.cpu is not None else None

    # ------------------------------------------------------------ CPU

    def server_tick(self, t: float) -> None:
        """An alignment tick at ``t``: a burst of ``server_tick`` on the server's process
        (it delays the server's later bursts; nothing else waits for it)."""
        if self._tick > 0.0:
            assert self.cpu is not None
            self.cpu.server.burst(t, self._tick)

    def server_free(self, t: float) -> float:
        """When the server process's loop thread is free of the bursts queued on it by
        ``t`` (``t`` if idle, or without a CPU stage)."""
        if self.cpu is None:
            return t
        free = self.cpu.server.free
        return free if free > t else t

    # ------------------------------------------------------------ MQTT publish

    def publish(
        self,
        client: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        payload_bits: int,
        subscribers: Sequence[int],
    ) -> None:
        """``client`` publishes now; the broker fans the message out to ``subscribers``.

        ``subject`` is the node the message is about (the server ``n`` for a
        broadcast, whose deliveries are then keyed by each subscriber). With per-host
        clients, a node publishes through its host's client and a subscriber node is
        reached through its host's client.
        """
        now = self.k.now
        if self.host_clients:
            cl = self.client_of
            client = cl[client]
            subs = tuple(dict.fromkeys(cl[s] for s in subscribers))
            if self.bundle and (client != self.server or kind == COMMAND):
                # a host's states to the server, or the server's commands to one host
                to = subs[0] if client == self.server else self.server
                key = (client, to)
                due = self._bundler.add(key, (kind, subject, index, payload, payload_bits),
                                        subs, now)
                if due is not None:  # a new turn: its PUBLISH leaves when due
                    self.k.at(due, self._flush, key)
                return
        else:
            subs = tuple(subscribers)
        self._client_publish(
            Msg(client, kind, subject, index, payload, payload_bits, subs, 0, now, now))

    def _client_publish(self, m: Msg) -> None:
        """``m.client``'s process spends its publish burst; then the PUBLISH leaves. The
        publish time becomes the burst's start: a live process stamps a message when its
        thread gets to the handler that sends it, so the wait for the thread is before
        the stamp, not in the latency."""
        proc = self._proc[m.client]
        if proc is None:
            self._publish_try(m)
        else:
            m.t_pub, end = proc.span(m.t_pub, self._cost(m))
            self.k.at(end, self._burst_done if self._lock_switch > 0.0 else self._net_send, m)

    def _net_send(self, m: Msg) -> None:
        """The loop thread has handed ``m`` over: a process with a network thread
        writes it there (the PUBLISH leaves at that burst's end); else it leaves now."""
        proc = self._proc[m.client]
        if proc is None or not proc.threaded:
            self._publish_try(m)
        else:
            self.k.at(proc.net_span(self.k.env.now, False)[0], self._publish_try, m)

    def _cost(self, m: Msg) -> float:
        """CPU of ``m``'s client process to send or receive it: its demand, plus its
        per-record CPU for each record of a bundle beyond the first."""
        d = self._demand[m.client]
        if isinstance(m.payload, Bundle):
            d += (len(m.payload) - 1) * self._record[m.client]
        return d

    def _burst_done(self, m: Msg) -> None:
        """(``lock_switch > 0``) The publish burst of ``m`` has ended: the PUBLISH leaves
        now if its process's thread is idle and nothing of it waits to leave, else
        after those, when the thread next waits or ``lock_switch`` after the first
        waiting one's burst ended (:meth:`_leave`). Live, paho's network thread writes
        the packet and needs the interpreter lock, which the loop thread gives up when
        it next waits, or when the interpreter makes it switch: what a busy process
        publishes leaves after its backlog, in order."""
        proc = self._proc[m.client]
        assert proc is not None
        now = self.k.now
        box = self._outbox.get(proc.name)
        if box is not None:  # a check is pending for the earlier ones: join them
            box[1].append(m)
        elif proc.free > now:
            due = now + self._lock_switch
            self._outbox[proc.name] = (due, [m])
            self.k.at(min(proc.free, due), self._leave, m.client)
        else:
            self._net_send(m)

    def _leave(self, client: int) -> None:
        """The process of ``client`` was due to be idle or to switch: if it is idle or
        the switch is due, every PUBLISH waiting in its outbox leaves, in order; else
        look again when it is next free (or the switch is due)."""
        proc = self._proc[client]
        assert proc is not None
        now = self.k.now
        due, box = self._outbox[proc.name]
        if proc.free > now and due > now:
            self.k.at(min(proc.free, due), self._leave, client)
            return
        del self._outbox[proc.name]
        for m in box:
            self._net_send(m)

    def _flush(self, key: tuple[int, int]) -> None:
        """Bundle: the open turn from ``key[0]`` to ``key[1]`` leaves as one PUBLISH."""
        self._client_publish(self._bundler.take(key, self.k.now))

    def _publish_try(self, m: Msg) -> None:
        """A try of the publisher → broker hop, leaving now."""
        m.t_sent = self.k.env.now
        if self._send_publish(m, True, self._broker_receive):
            self._resend(m, self._publish_try)

    def _send_publish(self, m: Msg, up: bool, on_arrive: Callable[[Msg], None]) -> bool:
        """Send ``m`` on its client's link at ``m.t_sent`` (``on_arrive(m)`` at its
        arrival); True if the sender's QoS 1 timer fires (datagram: lost or late)."""
        arr, lost = self.transmit(m, up, self.wire_bytes(m.bits), on_arrive)
        return self.datagram and self.qos1 and (lost or arr > m.t_sent + self.timeout)

    def _resend(self, m: Msg, fn: Callable[[Msg], None]) -> None:
        """QoS 1: the next try of ``m``'s hop when its timer fires, unless retries are spent."""
        if m.attempt >= self.max_retries:
            self.gave_up += 1
            return
        self.retransmissions += 1
        self.k.at(m.t_sent + self.timeout, fn, m.resent())

    def _broker_receive(self, m: Msg) -> None:
        """The broker serves the PUBLISH, acknowledges it and fans it out."""
        now = self.k.env.now
        subject = m.subject
        subs = m.subs
        dsubj = [s for s in subs] if subject == self.server else [subject] * len(subs)
        t_ack, departs = self.broker.serve_publish(now, m.kind, subject, m.index, m.attempt,
                                                   dsubj)
        if self.qos1 and self._puback(m, False, t_ack, now):
            self._resend(m, self._publish_try)
        kind, index, payload, bits, t_pub = m.kind, m.index, m.payload, m.bits, m.t_pub
        if isinstance(payload, Bundle):  # its one receiver counts it in the broker's order
            key, dropped = self._bundler.receiver_key(payload)
            if dropped:
                self.forced_drops = self.forced_drops | {key}
            kind, ds, index = key
            dsubj = [ds]
        for sub, ds, d in zip(subs, dsubj, departs, strict=True):
            # the broker's first try towards ``sub`` (Msg.to, inlined: the fan-out's hot loop)
            self._deliver_try(Msg(sub, kind, ds, index, payload, bits, (), 0, t_pub, d))

    def _puback(self, m: Msg, up: bool, t: float, now: float) -> bool:
        """Send the PUBACK of ``m`` (received ``now``) on its client's link at ``t``; True
        if the sender's QoS 1 timer fires first (datagram: the PUBACK is lost or late
        and the timer was still running at ``now``; over a stream the PUBACK is only
        counted traffic)."""
        if not self.datagram:
            self.count_packet(m.client, up, self._ack_b, t)
            return False
        a_arr, a_lost = self.hop(m.client, up, m.kind + ACK, m.subject, m.index, m.attempt,
                                 self._ack_b, t)
        late = m.t_sent + self.timeout
        return now <= late and (a_lost or a_arr > late)

    def _deliver_try(self, m: Msg) -> None:
        """A try of the broker → subscriber hop, leaving the broker at ``m.t_sent``."""
        if self._send_publish(m, False, self._client_receive):
            self._resend(m, self._redeliver)

    def _redeliver(self, m: Msg) -> None:
        """QoS 1: the broker serves a redelivery, then sends it."""
        m.t_sent = self.broker.serve_delivery(self.k.env.now, m.kind, m.subject, m.index,
                                              m.attempt)
        self._deliver_try(m)

    def _client_receive(self, m: Msg) -> None:
        """The subscriber receives ``m``: PUBACK (QoS 1), then hand it to the application
        (after its process's burst, if any). The latency ends when the process takes
        the message, the burst's start: a live receipt waits for the process (paho's
        thread needs the interpreter lock the loop thread holds while it serves its
        backlog); with ``lock_switch`` a copy
        reaching a busy process is read with its batch (:meth:`_read_batch`)."""
        now = self.k.env.now
        m.t_recv = now
        if self.qos1 and self._puback(m, True, now, now):
            self._resend(m, self._redeliver)
        if not self._app_stage:
            self.deliver(m)
            return
        proc = self._proc[m.client]
        if proc is None:
            self._hand_over(m)
        elif proc.threaded:  # paho's thread reads it; the latency ends at its burst's end
            read = m.t_read  # already read, if the stream held it (read_held)
            if read != read:
                read = proc.net_span(now, True)[1]
            self.k.at(read if read > now else now, self._loop_receive, m)
        else:  # the latency ends when the process gets to it (live's stamp), not later
            busy = proc.free > now
            m.t_recv, end = proc.span(now, self._cost(m))
            if busy and self._lock_switch > 0.0:
                m.t_recv = self._read_batch(proc.name, now, m.t_recv)
            self.k.at(end, self._hand_over, m)

    def read_held(self, m: Msg, resent: bool) -> None:
        """A copy the stream holds behind a lost segment, or one arriving on a resend,
        reaches a process with a network thread: the thread reads it now, and the loop thread gets
        it when it is handed on (:meth:`_client_receive`) — a held copy no earlier than
        that read's end, a resent one at once. Live's shim delays and resends a copy
        after paho's thread has read it (a resent one at its first arrival), so a batch
        released after a loss costs the receiving loop one call each, in order, not a
        network wake-up each behind the interpreter lock."""
        if not self._app_stage:
            return
        proc = self._proc[m.client]
        if proc is not None and proc.threaded:
            now = self.k.env.now
            end = proc.net_span(now, True)[1]
            m.t_read = now if resent else end

    def _loop_receive(self, m: Msg) -> None:
        """(A process with a network thread) ``m`` is stamped at the end of that
        thread's burst: a loop-thread burst of its cost is charged, and the application
        gets it at once (of the orders scored against live runs, the one that predicts
        them best: docs/concepts/decisions.md)."""
        proc = self._proc[m.client]
        assert proc is not None
        now = self.k.env.now
        m.t_recv = now  # the network thread's burst ends: the latency ends here
        proc.burst(now, self._cost(m))
        self._hand_over(m)

    def _read_batch(self, proc: str, now: float, start: float) -> float:
        """(``lock_switch > 0``) When a copy reaching a busy process at ``now`` is read:
        with the batch read when the thread next frees (its burst's ``start``, FCFS) or
        ``lock_switch`` after the batch's first copy arrived, whichever is first; a copy
        arriving before an open batch is read joins it. Live, paho's network thread reads
        the socket (and stamps the receipt) when it gets the interpreter lock, which the
        busy loop thread gives up when it waits or at the switch interval: the live
        server's receipts come in clusters 10-30 µs apart, not one handling apart."""
        bt = self._inbox.get(proc, -math.inf)
        if bt <= now:  # no batch open: this copy opens one
            bt = start if start < now + self._lock_switch else now + self._lock_switch
            self._inbox[proc] = bt
        return bt

    def _hand_over(self, m: Msg) -> None:
        """The receiving client's application gets ``m``: a bundle record by record; a
        host client's message to each of its nodes it is for (in node order)."""
        deliver = self.deliver
        c = m.client
        if isinstance(m.payload, Bundle):  # to the server, or commands to a host's nodes
            for kind, subject, index, payload, bits in m.payload:
                to = c if c == self.server else subject
                deliver(Msg(to, kind, subject, index, payload, bits, (), m.attempt, m.t_pub,
                            m.t_sent, m.t_recv))
        elif not self.host_clients or c == self.server:
            deliver(m)
        else:
            # the broadcast (a trigger) to every node of the host; a message about one
            # node (command, re-request) to that node
            nodes = self.members[c] if m.kind == TRIGGER else (m.subject,)
            for j in nodes:
                deliver(Msg(j, m.kind, j, m.index, m.payload, m.bits, (), m.attempt, m.t_pub,
                            m.t_sent, m.t_recv))
