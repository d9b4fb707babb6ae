"""Network impairment applied in the live clients (kernel ``netem`` is not needed).

Each live process owns one access link (a host's ``net.host_link`` or the server's
``net.server_link``). Its :class:`Impairment` decides, per message and direction,
the extra one-way delay drawn from the link's ``latency`` distribution and whether
the message is lost (the link's Bernoulli or Gilbert–Elliott ``loss``). A lost
message is resent by the DES transport's rules (:mod:`sigma_des.net.resend`: ``stream``
waits ``rto · 2^a`` after lost attempt ``a`` and keeps each direction in order,
``datagram`` with QoS 1 waits ``qos1_timeout``, with QoS 0 drops it; after
``max_retries`` lost resends it is gone). Draws use the counter-based streams
keyed by (link, direction, kind, subject, index, attempt): same seed, same
impairment decisions. A Bernoulli loss uses the DES's own draw of that packet: stream
``lossu.<host|server>.<up|down>`` at ``(kind, subject, index, attempt)``, as
:class:`~sigma_des.net.links.Links` draws it, so a live run and its DES lose the same
messages (with a stream, one triple loss holds a connection 1.4 s: which messages are
lost decides a lossy cell, not only how many). Outgoing messages are delayed before
they are published, incoming ones after they were received; bandwidth serialization is not emulated
(loopback is far faster than the modelled links).

With ``tc netem`` available, users can instead impair the loopback interface,
e.g. ``tc qdisc add dev lo root netem delay 5ms 1ms loss 10%`` (then run with
``--no-impair``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from sigma_des.core.rng import RandomStreams
from sigma_des.net.loss import LossProcess
from sigma_des.net.resend import InOrderRelease, walk_tries
from sigma_des.net.spec import LinkSpec, NetSpec

if TYPE_CHECKING:  # only for annotations: the shim itself needs no MQTT client
    from sigma_des.live.ledger import Ledger
    from sigma_des.live.loop import Client, Loop

__all__ = ["Impairment", "ImpairedSender", "UP", "DOWN"]

UP, DOWN = 0, 1


class Impairment:
    """Delay and loss decisions of one access link.

    Args:
        link: the link's spec.
        net: the network spec (transport, QoS, rto, retries).
        streams: the run's random streams.
        link_id: the link index (hosts 0..H-1, server H), as in the DES.
        enabled: False: no extra delay and no loss (the bare loopback).
        server: the server's link (the DES's ``lossu.server.*`` draws; else a host's).
    """

    def __init__(
        self, link: LinkSpec, net: NetSpec, streams: RandomStreams, link_id: int,
        enabled: bool = True, server: bool = False,
    ) -> None:
        self.link = link
        self.net = net
        self.link_id = link_id
        self.lat_stream = streams.stream("live.latency")
        self.loss = LossProcess(link.loss, streams.stream("live.loss"), link_id)
        side = "server" if server else "host"
        self._u = [streams.stream(f"lossu.{side}.{d}") for d in ("up", "down")]  # UP, DOWN
        lossless = link.loss.model == "bernoulli" and link.loss.p == 0.0
        zero = all(link.latency_of(up).is_constant and link.latency_of(up).mean_value() == 0.0
                   for up in (True, False))
        self.enabled = enabled and not (lossless and zero)
        self._lossless = lossless
        self._order = [InOrderRelease(), InOrderRelease()]  # UP, DOWN (stream transport)
        self.lost = 0
        self.resent = 0
        self.gave_up = 0

    def arrival(self, t: float, direction: int, kind: int, subject: int, index: int) -> float:
        """When one message that enters this link at ``t`` is handed on (s); ``inf`` if
        it is lost (``t`` itself without impairment).

        Args:
            t: time the message enters this link (s).
            direction: :data:`UP` (leaving this process) or :data:`DOWN` (arriving).
            kind: message kind (``sigma_des.live.wire``).
            subject: node index (or the server's index for triggers).
            index: frame, tick or re-request index.
        """
        if not self.enabled:
            return t
        ids = (self.link_id, direction, kind, subject, index)
        lat = float(self.link.latency_of(direction == UP).sample(self.lat_stream, *ids)[0])
        stream = self.net.transport == "stream"
        sent = t
        if not self._lossless:
            tries = walk_tries(self.net, t, lambda t_try, attempt: self._lost(
                t_try, direction, kind, subject, index, attempt))
            self.lost += tries.lost
            self.resent += tries.resent
            if tries.gave_up:
                self.gave_up += 1
                if stream:  # it still takes its place in the order, at its last try
                    self._order[direction].give_up(tries.last)
            sent = tries.sent
            if math.isinf(sent):
                return sent
        if stream:
            return self._order[direction].release(sent + lat)
        return sent + lat

    def delay(self, t: float, direction: int, kind: int, subject: int, index: int) -> float:
        """:meth:`arrival` less ``t``: the extra delay (s); ``inf`` if it is lost."""
        return self.arrival(t, direction, kind, subject, index) - t


    def _lost(self, t: float, direction: int, kind: int, subject: int, index: int,
              attempt: int) -> bool:
        """Is this try lost? Bernoulli: the DES's draw of the same packet; Gilbert–
        Elliott (its state depends on time): the shim's own process."""
        spec = self.link.loss
        if spec.model == "bernoulli":
            return bool(self._u[direction].uniform(kind, subject, index, attempt)[()] < spec.p)
        return bool(self.loss.lost(t, direction, kind, subject, index, attempt)[0])


class ImpairedSender:
    """Mixin of the live processes that publish through their access link's shim.

    The host and the server both send this way: the message is dropped if the shim
    loses it for good, counted in the wire-byte ledger, and published after the
    drawn one-way delay (at once when there is none).
    """

    loop: Loop
    client: Client
    impair: Impairment
    ledger: Ledger
    qos: int

    def _publish(self, topic: str, payload: bytes, t: float, kind: int, subject: int,
                 index: int) -> None:
        at = self.impair.arrival(t, UP, kind, subject, index)
        if math.isinf(at):
            return
        self.ledger.sent(t, len(topic), len(payload), self.qos)
        if at > t:
            self.loop.call_at(at, self.client.publish, topic, payload, self.qos)
        else:
            self.client.publish(topic, payload, self.qos)
