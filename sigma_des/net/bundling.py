"""Bundles: a client's publishes of one loop turn as one PUBLISH (``deployment.bundle``).

With ``deployment.bundle`` a host client's state publishes of one loop turn leave as one
PUBLISH, and so do the server's commands of one turn to one host; the receiver hands
them over record by record (docs/concepts/deployment.md, "Bundles"). A turn is the
publishes of one instant or, with a CPU stage, every publish made while the sender's
process is busy: they join the PUBLISH that leaves when it is free. :class:`Bundler`
collects the turns and keys each bundle's hops by its place among its host's bundles of
its first record's ``(kind, index)`` (:mod:`sigma_des.net.bundlekeys`, live's rule):
counted at the sender for the publisher → broker hop, at the broker's fan-out for the
broker → receiver hop. :class:`~sigma_des.net.network.Network` owns one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sigma_des.net.bundlekeys import BundleKeys
from sigma_des.net.cpu import Process
from sigma_des.net.message import Msg

__all__ = ["Bundle", "Bundler", "Record"]

#: one record of a bundle: ``(kind, subject, index, payload, payload_bits)``
Record = tuple[int, int, int, Any, int]


class Bundle(tuple[Record, ...]):
    """The payload of a bundled PUBLISH: the records one client published to one
    receiver in one loop turn (a host's states; the server's commands to a host), in
    publish order, handed to the receiving application one by one, each with the
    bundle's publish time (live stamps them in the turn that sends them)."""

    __slots__ = ()


class Bundler:
    """The open turns of every (sender, receiver) pair, and the bundles' draw keys. It
    holds nothing of the network (no callback: a retired run is freed without the cyclic
    collector); the network schedules each turn's send and publishes what it returns.

    Args:
        procs: each client's process (None: no CPU burst).
        server: the server's client id.
        client_of: each node's client (a host client's id is its first node).
        lead_drops: ``(kind, subject, index)`` of first records whose bundle a drop
            fault drops.
    """

    __slots__ = ("procs", "server", "client_of", "lead_drops", "_pending", "_up_keys",
                 "_down_keys")

    def __init__(self, procs: Sequence[Process | None], server: int,
                 client_of: Sequence[int], lead_drops: frozenset[tuple[int, int, int]]
                 ) -> None:
        self.procs = procs
        self.server = server
        self.client_of = client_of
        self.lead_drops = lead_drops
        self._pending: dict[tuple[int, int], list[tuple[Record, tuple[int, ...]]]] = {}
        # draw keys, counted where each hop starts: the sender, the broker
        self._up_keys = BundleKeys()
        self._down_keys = BundleKeys()

    def add(self, key: tuple[int, int], rec: Record, subs: tuple[int, ...], now: float
            ) -> float | None:
        """Keep ``rec`` for the PUBLISH of this loop turn from client ``key[0]`` to
        ``key[1]`` (a host's states to the server; the server's commands to a host); the
        time the turn's PUBLISH is due if ``rec`` opens the turn, else None.

        The first record of a turn is due when the sender's process is next free (now,
        without a CPU stage or when idle), after every event already due then: records
        published meanwhile (jobs completing while the process serves a burst, as a
        live host's loop handles the timers that fell due while it was busy) join it.
        The send's own burst then makes the next turn.
        """
        pend = self._pending.get(key)
        due = None
        if not pend:
            pend = self._pending[key] = []
            proc = self.procs[key[0]]
            due = proc.free if proc is not None and proc.free > now else now
        pend.append((rec, subs))
        return due

    def records(self, key: tuple[int, int]) -> int:
        """Records in the open turn of ``key`` (0: none)."""
        return len(self._pending.get(key, ()))

    def take(self, key: tuple[int, int], now: float) -> Msg:
        """The open turn of ``key`` as one PUBLISH leaving now (its payload the records
        together), keyed by its place among the bundles of its first record's ``(kind,
        index)`` that this host's client sent, or the server sent it."""
        pend = self._pending.pop(key)
        kind, subject, index, _p, _b = pend[0][0]
        host = key[1] if key[0] == self.server else key[0]
        kind, subject, index = self._up_keys.key(host, host, kind, subject, index)
        recs = Bundle(r for r, _s in pend)
        bits = sum(r[4] for r in recs)
        return Msg(key[0], kind, subject, index, recs, bits, pend[0][1], 0, now, now)

    def receiver_key(self, b: Bundle) -> tuple[tuple[int, int, int], bool]:
        """The draw key of ``b``'s broker → receiver hop: its place among the bundles of
        its first record's ``(kind, index)`` on its host's channel, counted in the order
        the broker sends them (as a live receiver counts them on receipt); and whether a
        drop fault names its first record."""
        kind, subject, index = b[0][:3]
        host = self.client_of[subject]
        key = self._down_keys.key(host, host, kind, subject, index)
        return key, (kind, subject, index) in self.lead_drops
