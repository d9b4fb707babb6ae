"""The MQTT broker: one FIFO server (docs/concepts/model.md, "Network").

An inbound PUBLISH costs ``publish_service`` plus one ``delivery_service`` per
subscriber; delivery ``j`` leaves after the publish part and ``j+1`` delivery
parts. The PUBACK to the publisher leaves after the publish part and costs the
broker nothing. A QoS 1 redelivery is one more ``delivery_service``. Every
service time is drawn by ``(kind, subject, index, attempt)`` from the streams
``svc.publish`` and ``svc.delivery``, so results do not depend on event order.

With a CPU stage (:mod:`sigma_des.net.cpu`) the broker is a process on its
machine's cores: a service starts at ``max(now, busy, core_free)`` on the
lowest-index core with the smallest free time, every service time is multiplied
by the background slow-down, and the core is held until the last delivery leaves.

The broker only computes times: the client side (links, transports, QoS) is in
:mod:`sigma_des.net.network`, which sends what the broker's times say.
"""

from __future__ import annotations

from collections.abc import Sequence

from sigma_des.core.draws import DrawCache
from sigma_des.core.rng import RandomStreams
from sigma_des.net.cpu import Process
from sigma_des.net.links import dist_cache
from sigma_des.net.spec import BrokerSpec

__all__ = ["Broker"]


class Broker:
    """The single-threaded broker's service times, busy period and load counters.

    Args:
        spec: the broker's service-time distributions.
        streams: root random streams.
        clients: number of clients (nodes plus the server).
        warmup: service before this time is not counted.
        end: service at or after this time is not counted.
        process: the broker's process on its machine's cores (None: no CPU stage, the
            broker has a core of its own).

    Attributes:
        busy: time the server is free again (s).
        work: service seconds inside the metrics window ``[warmup, end)``.
        max_wait: longest wait of a PUBLISH arriving in the window before its service (s).
        publish_draws: service-time draws of inbound PUBLISHes (read-only use).
        delivery_draws: service-time draws of deliveries (read-only use).
    """

    def __init__(
        self, spec: BrokerSpec, streams: RandomStreams, clients: int, warmup: float,
        end: float, process: Process | None = None,
    ) -> None:
        # a broker that spends nothing holds no core (a zero demand is no burst)
        idle = all(d.dist == "constant" and d.value == 0.0
                   for d in (spec.publish_service, spec.delivery_service))
        self.process = None if idle else process
        self.warmup = warmup
        self.end = end
        self.publish_draws: DrawCache = dist_cache(
            clients, spec.publish_service, streams, "svc.publish"
        )
        self.delivery_draws: DrawCache = dist_cache(
            clients, spec.delivery_service, streams, "svc.delivery"
        )
        self.busy = 0.0
        self.work = 0.0
        self.max_wait = 0.0

    def serve_publish(
        self,
        now: float,
        kind: int,
        subject: int,
        index: int,
        attempt: int,
        delivery_subjects: Sequence[int],
    ) -> tuple[float, list[float]]:
        """Serve a PUBLISH arriving ``now`` and its deliveries, in that order.

        Args:
            now: arrival time of the PUBLISH at the broker.
            kind: message kind.
            subject: the node the message is about.
            index: frame (or tick) index.
            attempt: transmission attempt of the PUBLISH.
            delivery_subjects: draw subject of each delivery, in delivery order.

        Returns:
            (time the PUBACK leaves, departure time of each delivery)
        """
        s_pub = self.publish_draws.get(kind, subject, index, attempt)
        s_del = [self.delivery_draws.get(kind, d, index, attempt) for d in delivery_subjects]
        proc = self.process
        c = 0
        if proc is None:
            start = now if now > self.busy else self.busy
        else:
            sc = proc.scale
            s_pub = s_pub * sc
            s_del = [x * sc for x in s_del]
            length = s_pub
            for x in s_del:
                length += x
            wait = proc.run_wait(now, length / sc, length)
            start, c = proc.acquire(now, length, wait)  # its thread is free at ``busy``
        if self.warmup <= now < self.end:
            self.max_wait = max(self.max_wait, start - now)
        t_ack = start + s_pub
        d = t_ack
        departs = []
        for sd in s_del:
            d += sd
            departs.append(d)
        # free exactly when the last delivery leaves (same float as that departure)
        self.busy = d
        if proc is not None:
            proc.hold(now, start, c, d)
        self._count_work(start, d)
        return t_ack, departs

    def serve_delivery(
        self, now: float, kind: int, subject: int, index: int, attempt: int
    ) -> float:
        """Serve one redelivery (QoS 1 resend) asked for ``now``; its departure time."""
        s_del = self.delivery_draws.get(kind, subject, index, attempt)
        proc = self.process
        if proc is None:
            start = now if now > self.busy else self.busy
            end = start + s_del
        else:
            length = s_del * proc.scale
            start, c = proc.acquire(now, length, proc.run_wait(now, s_del, length))
            end = start + length
            proc.hold(now, start, c, end)
        self.busy = end
        self._count_work(start, end)
        return end

    def carried(self, busy: float, work: float, max_wait: float) -> None:
        """Service given elsewhere (the compiled core): free again at ``busy`` at the
        latest, ``work`` more service seconds, a longest wait of ``max_wait``."""
        self.busy = max(self.busy, busy)
        self.work += work
        self.max_wait = max(self.max_wait, max_wait)

    def _count_work(self, a: float, b: float) -> None:
        """Count busy time [a, b) inside the metrics window."""
        lo = a if a > self.warmup else self.warmup
        hi = b if b < self.end else self.end
        if hi > lo:
            self.work += hi - lo
