"""MQTT over the modelled links, and the broker (DESIGN §2).

Links and transports (FIFO serialization, latency, loss, in-order streams) are
in :mod:`sigma_des.net.links`; this module adds MQTT on top. QoS 1 over
``datagram`` resends with DUP after ``qos1_timeout`` when no PUBACK came, so
duplicates can reach receivers; over ``stream`` the PUBACKs are counted traffic.

The broker is one FIFO server: an inbound PUBLISH costs ``publish_service`` plus
one ``delivery_service`` per subscriber; delivery ``j`` leaves after the publish
part and ``j+1`` delivery parts. PUBACKs leave the broker after the publish part
and cost the broker nothing. All downlink traffic leaves the broker in service
order, so downlink FIFO reservations can be made when the broker serves.

This module knows nothing of alignment methods or aircraft: a delivered message
is handed to the ``deliver`` callback given at construction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from sigma_des.config import Scenario
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.kinds import ACK, COMMAND, STATE, TRIGGER
from sigma_des.net.links import Links, dist_cache
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, payload_bytes, publish_bytes

__all__ = ["Network"]

Deliver = Callable[[int, int, int, int, Any, float], None]


class Network(Links):
    """Links, transport, QoS and broker for ``n`` nodes plus the server.

    Args:
        kernel: the SimPy glue.
        sc: the scenario.
        streams: root random streams.
        deliver: ``deliver(client, kind, subject, index, payload, t_publish)`` is
            called at the application-level arrival of every PUBLISH (duplicates
            included) at a client.
        warmup: traffic before this time is not counted.
    """

    def __init__(
        self, kernel: Kernel, sc: Scenario, streams: RandomStreams, deliver: Deliver, warmup: float
    ) -> None:
        # drop faults: the first transmission on the broker-to-receiver hop is lost
        kinds = {"trigger": TRIGGER, "state": STATE, "command": COMMAND}
        drops = {(kinds[f.message], f.node, f.frame) for f in sc.faults if f.kind == "drop"}
        super().__init__(kernel, sc, streams, warmup, drops)
        self.deliver = deliver
        net = sc.net
        self.qos1 = net.qos == 1
        self.timeout = net.qos1_timeout
        self._topic = net.topic_bytes
        nsub = self.n + 1
        self._svc_pub = dist_cache(nsub, sc.broker.publish_service, streams, "svc.publish")
        self._svc_del = dist_cache(nsub, sc.broker.delivery_service, streams, "svc.delivery")
        self.broker_busy = 0.0
        self.broker_work = 0.0  # service seconds in the metrics window
        self.broker_max_wait = 0.0
        self._wire_cache: dict[int, int] = {}
        self._ack_b = frame_bytes(PUBACK_BYTES, net.tcpip_bytes, net.ethernet_bytes)

    # ------------------------------------------------------------ sizes

    def wire_bytes(self, payload_bits: int) -> int:
        """Wire bytes of one PUBLISH carrying ``payload_bits`` at the scenario's QoS."""
        b = self._wire_cache.get(payload_bits)
        if b is None:
            b = self._wire_cache[payload_bits] = frame_bytes(
                publish_bytes(self._topic, payload_bytes(payload_bits), 1 if self.qos1 else 0),
                self.sc.net.tcpip_bytes,
                self.sc.net.ethernet_bytes,
            )
        return b

    @property
    def ack_bytes(self) -> int:
        """Wire bytes of one PUBACK."""
        return self._ack_b

    def _work(self, a: float, b: float) -> None:
        """Count broker busy time [a, b) inside the metrics window."""
        lo = a if a > self.warmup else self.warmup
        hi = b if b < self.end else self.end
        if hi > lo:
            self.broker_work += hi - lo

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
        t = self.k.env._now
        nbytes = self.wire_bytes(bits)
        arr, lost = self._transmit(
            client,
            True,
            kind,
            subject,
            index,
            attempt,
            nbytes,
            t,
            self._broker_receive,
            (client, kind, subject, index, payload, bits, subs, attempt, t_pub, t),
        )
        if self.datagram and self.qos1 and (lost or arr > t + self.timeout):
            self._schedule_resend(
                t + self.timeout,
                attempt,
                self._publish_try,
                (client, kind, subject, index, payload, bits, subs, attempt + 1, t_pub),
            )

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
        now = self.k.env._now
        s_pub = self._svc_pub.get(kind, subject, index, attempt)
        broadcast = subject == self.server
        dsubj = [s if broadcast else subject for s in subs]
        s_del = [self._svc_del.get(kind, d, index, attempt) for d in dsubj]
        start = now if now > self.broker_busy else self.broker_busy
        if self.warmup <= now < self.end:
            self.broker_max_wait = max(self.broker_max_wait, start - now)
        # PUBACK back to the publisher
        if self.qos1 and not self.datagram:
            self._count(client, False, self._ack_b, start + s_pub)
        elif self.qos1:
            ack_t = start + s_pub
            a_arr, a_lost = self._hop(
                client, False, kind + ACK, subject, index, attempt, self._ack_b, ack_t
            )
            if now <= t_sent + self.timeout and (a_lost or a_arr > t_sent + self.timeout):
                self._schedule_resend(
                    t_sent + self.timeout,
                    attempt,
                    self._publish_try,
                    (client, kind, subject, index, payload, bits, subs, attempt + 1, t_pub),
                )
        d = start + s_pub
        for sub, ds, sd in zip(subs, dsubj, s_del, strict=True):
            d += sd
            self._deliver_try(sub, kind, ds, index, payload, bits, 0, t_pub, d)
        # free exactly when the last delivery leaves (same float as that departure)
        self.broker_busy = d
        self._work(start, d)

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
        nbytes = self.wire_bytes(bits)
        arr, lost = self._transmit(
            sub,
            False,
            kind,
            subject,
            index,
            attempt,
            nbytes,
            t_depart,
            self._client_receive,
            (sub, kind, subject, index, payload, bits, attempt, t_pub, t_depart),
        )
        if self.datagram and self.qos1 and (lost or arr > t_depart + self.timeout):
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
        now = self.k.env._now
        s_del = self._svc_del.get(kind, subject, index, attempt)
        start = now if now > self.broker_busy else self.broker_busy
        self.broker_busy = start + s_del
        self._work(start, start + s_del)
        self._deliver_try(sub, kind, subject, index, payload, bits, attempt, t_pub, start + s_del)

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
        now = self.k.env._now
        if self.qos1 and not self.datagram:
            self._count(sub, True, self._ack_b, now)
        elif self.qos1:
            a_arr, a_lost = self._hop(
                sub, True, kind + ACK, subject, index, attempt, self._ack_b, now
            )
            if now <= t_depart + self.timeout and (a_lost or a_arr > t_depart + self.timeout):
                self._schedule_resend(
                    t_depart + self.timeout,
                    attempt,
                    self._redeliver,
                    (sub, kind, subject, index, payload, bits, attempt + 1, t_pub),
                )
        self.deliver(sub, kind, subject, index, payload, t_pub)

    # ------------------------------------------------------------ accounting
