"""One message on one hop: the record the network passes along (docs/concepts/model.md, "Network").

A PUBLISH crosses two hops: publisher → broker (its ``client`` is the publisher,
``subs`` the clients the broker fans it out to) and broker → each subscriber (its
``client`` is that subscriber; ``subject`` is the draw subject of that delivery:
the subscriber itself for a broadcast). Each try of a hop is its own record,
sent at ``t_sent`` with its ``attempt`` number; a QoS 1 resend is a new record
(:meth:`Msg.resent`), so a record already in flight never changes under an event
that still holds it. ``(kind, subject, index, attempt)`` keys every random draw
of the hop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["Msg"]


@dataclass(slots=True, eq=False, repr=False)
class Msg:
    """One try of one PUBLISH on one hop.

    Attributes:
        client: the client on whose access link this hop travels (the publisher
            upstream, the subscriber downstream).
        kind: what the message carries (:mod:`sigma_des.net.kinds`).
        subject: the node the message is about (draw subject of the hop).
        index: frame (or tick) index.
        payload: what the application sent (opaque to the network).
        bits: payload size in bits (sets the wire size).
        subs: upstream: the clients the broker delivers to; downstream: ``()``.
        attempt: transmission attempt of this hop (0: the first).
        t_pub: when the application published it.
        t_sent: when this try left (the publisher, or the broker downstream).
        t_recv: when it reached the receiving MQTT client, before that client's CPU
            burst: the instant live stamps a receipt, to which its latency is measured
            (NaN until then, and for middlewares that deliver at receipt).
        t_read: when the receiving process's network thread finished reading a copy
            the stream held behind an earlier segment (read at its own arrival, handed
            to the loop when the gap is filled); NaN for every other copy.
    """

    client: int
    kind: int
    subject: int
    index: int
    payload: Any
    bits: int
    subs: tuple[int, ...]
    attempt: int
    t_pub: float
    t_sent: float
    t_recv: float = math.nan
    t_read: float = math.nan

    def resent(self) -> Msg:
        """The next try of this hop (``t_sent``: set when it leaves)."""
        return Msg(self.client, self.kind, self.subject, self.index, self.payload, self.bits,
                   self.subs, self.attempt + 1, self.t_pub, self.t_sent)

    def to(self, sub: int, subject: int, t_depart: float) -> Msg:
        """The broker's first try of delivering this PUBLISH to ``sub``, leaving at ``t_depart``."""
        return Msg(sub, self.kind, subject, self.index, self.payload, self.bits, (), 0,
                   self.t_pub, t_depart)

    def __repr__(self) -> str:
        return (f"Msg(client={self.client}, kind={self.kind}, subject={self.subject}, "
                f"index={self.index}, attempt={self.attempt}, t_pub={self.t_pub!r}, "
                f"t_sent={self.t_sent!r})")
