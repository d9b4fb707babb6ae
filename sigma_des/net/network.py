"""MQTT clients over the modelled links, through the broker (docs/MODEL.md, "Network").

Links and transports (FIFO serialization, latency, loss, in-order streams) are
in :mod:`sigma_des.net.links`, the broker's FIFO service in
:mod:`sigma_des.net.broker`; this module is the MQTT side: publish, QoS 1
PUBACKs and resends, receive. QoS 1 over ``datagram`` resends with DUP after
``qos1_timeout`` when no PUBACK came, so duplicates can reach receivers; over
``stream`` the PUBACKs are counted traffic. All downlink traffic leaves the
broker in service order, so downlink FIFO reservations are made when the broker
serves.

This module knows nothing of alignment methods or aircraft: a delivered message
is handed to the ``deliver`` callback given at construction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.broker import Broker
from sigma_des.net.kinds import ACK
from sigma_des.net.links import Links
from sigma_des.net.message import Msg
from sigma_des.net.spec import NetSetup
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, payload_bytes, publish_bytes

__all__ = ["Network"]

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
        self.broker = Broker(setup.broker, streams, self.n + 1, self.warmup, self.end)
        self._wire_cache: dict[int, int] = {}
        self._ack_b = frame_bytes(PUBACK_BYTES, net.tcpip_bytes, net.ethernet_bytes)

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
        broadcast, whose deliveries are then keyed by each subscriber).
        """
        now = self.k.now
        self._publish_try(
            Msg(client, kind, subject, index, payload, payload_bits, tuple(subscribers), 0,
                now, now)
        )

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
        """The subscriber receives ``m``: PUBACK (QoS 1), then hand it to the application."""
        now = self.k.env.now
        if self.qos1 and self._puback(m, True, now, now):
            self._resend(m, self._redeliver)
        self.deliver(m)
