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
from sigma_des.net.spec import NetSetup
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, payload_bytes, publish_bytes

__all__ = ["Network"]

Deliver = Callable[[int, int, int, int, Any, float], None]


class Network(Links):
    """Links, transport, QoS and broker for ``n`` nodes plus the server.

    Args:
        kernel: the SimPy glue.
        setup: the net's specs, topology, metrics window and link faults.
        streams: root random streams.
        deliver: ``deliver(client, kind, subject, index, payload, t_publish)`` is
            called at the application-level arrival of every PUBLISH (duplicates
            included) at a client.
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
        self._publish_try(
            client, kind, subject, index, payload, payload_bits, tuple(subscribers), 0, self.k.now
        )

    def _publish_try(
        self,
        client: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        bits: int,
        subs: tuple[int, ...],
        attempt: int,
        t_pub: float,
    ) -> None:
        t = self.k.env.now
        if self._send_publish(
            client,
            True,
            kind,
            subject,
            index,
            attempt,
            bits,
            t,
            self._broker_receive,
            (client, kind, subject, index, payload, bits, subs, attempt, t_pub, t),
        ):
            self._schedule_resend(
                t + self.timeout,
                attempt,
                self._publish_try,
                (client, kind, subject, index, payload, bits, subs, attempt + 1, t_pub),
            )

    def _send_publish(
        self,
        client: int,
        up: bool,
        kind: int,
        subject: int,
        index: int,
        attempt: int,
        bits: int,
        t: float,
        on_arrive: Callable[..., None],
        args: tuple[Any, ...],
    ) -> bool:
        """Send one PUBLISH on ``client``'s link at ``t`` (``on_arrive(*args)`` at its
        arrival); True if the sender's QoS 1 timer fires (datagram: lost or late)."""
        arr, lost = self.transmit(
            client, up, kind, subject, index, attempt, self.wire_bytes(bits), t, on_arrive, args
        )
        return self.datagram and self.qos1 and (lost or arr > t + self.timeout)

    def _schedule_resend(
        self, when: float, attempt: int, fn: Callable[..., None], args: tuple[Any, ...]
    ) -> None:
        if attempt >= self.max_retries:
            self.gave_up += 1
            return
        self.retransmissions += 1
        self.k.at(when, fn, *args)

    def _broker_receive(
        self,
        client: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        bits: int,
        subs: tuple[int, ...],
        attempt: int,
        t_pub: float,
        t_sent: float,
    ) -> None:
        now = self.k.env.now
        broadcast = subject == self.server
        dsubj = [s if broadcast else subject for s in subs]
        t_ack, departs = self.broker.serve_publish(now, kind, subject, index, attempt, dsubj)
        # PUBACK back to the publisher
        if self.qos1 and self._puback(client, False, kind, subject, index, attempt, t_ack,
                                      t_sent, now):
            self._schedule_resend(
                t_sent + self.timeout,
                attempt,
                self._publish_try,
                (client, kind, subject, index, payload, bits, subs, attempt + 1, t_pub),
            )
        for sub, ds, d in zip(subs, dsubj, departs, strict=True):
            self._deliver_try(sub, kind, ds, index, payload, bits, 0, t_pub, d)

    def _puback(
        self,
        client: int,
        up: bool,
        kind: int,
        subject: int,
        index: int,
        attempt: int,
        t: float,
        t_sent: float,
        now: float,
    ) -> bool:
        """Send the PUBACK on ``client``'s link at ``t`` for a PUBLISH sent at ``t_sent``
        and received ``now``; True if the sender's QoS 1 timer fires first (datagram:
        the PUBACK is lost or late and the timer was still running at ``now``; over a
        stream the PUBACK is only counted traffic)."""
        if not self.datagram:
            self.count_packet(client, up, self._ack_b, t)
            return False
        a_arr, a_lost = self.hop(client, up, kind + ACK, subject, index, attempt, self._ack_b, t)
        return now <= t_sent + self.timeout and (a_lost or a_arr > t_sent + self.timeout)

    def _deliver_try(
        self,
        sub: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        bits: int,
        attempt: int,
        t_pub: float,
        t_depart: float,
    ) -> None:
        """Broker → subscriber hop leaving the broker at ``t_depart``."""
        if self._send_publish(
            sub,
            False,
            kind,
            subject,
            index,
            attempt,
            bits,
            t_depart,
            self._client_receive,
            (sub, kind, subject, index, payload, bits, attempt, t_pub, t_depart),
        ):
            self._schedule_resend(
                t_depart + self.timeout,
                attempt,
                self._redeliver,
                (sub, kind, subject, index, payload, bits, attempt + 1, t_pub),
            )

    def _redeliver(
        self,
        sub: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        bits: int,
        attempt: int,
        t_pub: float,
    ) -> None:
        depart = self.broker.serve_delivery(self.k.env.now, kind, subject, index, attempt)
        self._deliver_try(sub, kind, subject, index, payload, bits, attempt, t_pub, depart)

    def _client_receive(
        self,
        sub: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        bits: int,
        attempt: int,
        t_pub: float,
        t_depart: float,
    ) -> None:
        now = self.k.env.now
        if self.qos1 and self._puback(sub, True, kind, subject, index, attempt, now, t_depart,
                                      now):
            self._schedule_resend(
                t_depart + self.timeout,
                attempt,
                self._redeliver,
                (sub, kind, subject, index, payload, bits, attempt + 1, t_pub),
            )
        self.deliver(sub, kind, subject, index, payload, t_pub)

