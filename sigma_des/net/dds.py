"""Brokerless DDS/RTPS publish/subscribe over the modelled links (``net.middleware = "dds"``).

The model (parameters and sources in :class:`sigma_des.net.spec.DdsSpec`, docs/concepts/peers.md):

* **Participants.** Every physics node and the server is one DDS participant with
  one middleware thread, a FIFO server for all its sends and receives. No broker: a
  packet crosses the writer's host uplink and the reader's host downlink.
* **User data.** One DATA per matched reader (``writer_cost`` each, in reader order;
  ``multicast``: one send the switch copies); the reader's thread spends
  ``reader_cost + executor_per_entity × entities`` before delivering. Only matched
  readers get samples (VOLATILE durability).
* **Reliability** (``reliable``): periodic HEARTBEATs, ACKNACKs naming lost samples,
  resends while within ``history_depth``, else a GAP (``gave_up``); a reliable reader
  delivers each writer's samples in order (head-of-line blocking).
* **Discovery.** SPDP announcements and SEDP endpoint records, all-to-all: discovery
  traffic grows with participants² × endpoints.

This module knows nothing of alignment methods or aircraft.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.links import dist_cache
from sigma_des.net.message import Msg
from sigma_des.net.network import Deliver, Network
from sigma_des.net.spec import NetSetup
from sigma_des.net.wire import frame_bytes, payload_bytes

__all__ = [
    "DdsNetwork",
    "RTPS_HEADER",
    "acknack_bytes",
    "data_bytes",
    "heartbeat_bytes",
    "make_network",
]

#: RTPS message header: 'RTPS', version, vendor id, GUID prefix [RTPS §8.3.3].
RTPS_HEADER = 20
#: INFO_TS (4 header + 8 timestamp) and INFO_DST (4 header + 12 GUID prefix) [RTPS §9.4.5].
INFO_TS, INFO_DST = 12, 16
#: DATA submessage without inline QoS: header 4, extraFlags 2, octetsToInlineQos 2,
#: readerId 4, writerId 4, writerSN 8; then the 4-byte CDR encapsulation header.
DATA_HEADER, ENCAPSULATION = 24, 4
#: HEARTBEAT: header 4, readerId 4, writerId 4, firstSN 8, lastSN 8, count 4.
HEARTBEAT = 32
#: ACKNACK with a one-word bitmap: header 4, ids 8, SN set (8 + 4 + 4), count 4.
ACKNACK = 32

# draw kinds of metatraffic (user kinds are < 16, PUBACK draws 16..31)
_HB, _AN, _SPDP, _SEDP, _GAP = 40, 41, 42, 43, 44


def data_bytes(payload_bits: int, unicast: bool = True) -> int:
    """RTPS message bytes of one DATA carrying ``payload_bits`` (padded to 4 bytes)."""
    body = -(-payload_bytes(payload_bits) // 4) * 4
    dst = INFO_DST if unicast else 0
    return RTPS_HEADER + dst + INFO_TS + DATA_HEADER + ENCAPSULATION + body


def heartbeat_bytes() -> int:
    """RTPS message bytes of one HEARTBEAT to one reader."""
    return RTPS_HEADER + INFO_DST + HEARTBEAT


def acknack_bytes() -> int:
    """RTPS message bytes of one ACKNACK to one writer."""
    return RTPS_HEADER + INFO_DST + ACKNACK


@dataclass(slots=True, eq=False, repr=False)
class Sample(Msg):
    """A writer's sample: the message (``client``: the writer) and its sequence number
    among that writer's samples (the reader's delivery order; always given, by
    keyword: it follows ``Msg``'s defaulted ``t_recv``)."""

    seq: int = -1


def make_network(
    kernel: Kernel, setup: NetSetup, streams: RandomStreams, deliver: Deliver
) -> Network:
    """The network of ``setup.net.middleware``: an MQTT broker, or brokerless DDS.

    Args:
        kernel: the SimPy glue.
        setup: the net's specs, topology, metrics window and link faults.
        streams: root random streams.
        deliver: called at every application-level arrival (see :class:`Network`).
    """
    if setup.net.middleware == "dds":
        return DdsNetwork(kernel, setup, streams, deliver)
    return Network(kernel, setup, streams, deliver)


class DdsNetwork(Network):
    """DDS participants over the links; the same ``publish`` interface as the broker.

    The broker's counters stay zero (there is none). Extra counters:
    ``dds_meta_messages`` (HEARTBEAT, ACKNACK, SPDP, SEDP messages sent in the
    window), ``dds_unmatched`` (user samples not sent: reader not yet discovered).
    """

    def __init__(
        self, kernel: Kernel, setup: NetSetup, streams: RandomStreams, deliver: Deliver
    ) -> None:
        super().__init__(kernel, setup, streams, deliver)
        d = self.spec = setup.dds
        n = self.n
        nsub = n + 1
        self._w_cost = dist_cache(nsub, d.writer_cost, streams, "dds.writer")
        self._r_cost = dist_cache(nsub, d.reader_cost, streams, "dds.reader")
        self.thread = [0.0] * nsub  # participant middleware threads: busy until
        ent = [d.endpoints + 2] * n + [d.endpoints + n]
        self.entities = ent
        self._dispatch = [d.executor_per_entity * e for e in ent]
        eth, udp = setup.net.ethernet_bytes, d.udpip_bytes
        self._frame = lambda b: frame_bytes(b, udp, eth)  # noqa: E731
        self._hb_b = self._frame(heartbeat_bytes())
        self._an_b = self._frame(acknack_bytes())
        self._spdp_b = self._frame(RTPS_HEADER + INFO_TS + d.spdp_bytes)
        self._sedp_b = [self._frame(RTPS_HEADER + INFO_DST + e * d.sedp_bytes) for e in ent]
        self._data_b: dict[tuple[int, bool], int] = {}
        # discovery: heard[q] = participants q has heard (SPDP); matched[a] = readers a knows
        self.heard: list[set[int]] = [set() for _ in range(nsub)]
        self.matched: list[set[int]] = [set() for _ in range(nsub)]
        # reliability: samples written per writer (participant, kind, topic subject);
        # lost samples per writer/reader participant pair
        self._written: dict[tuple[int, int, int], int] = {}
        self._lost: dict[tuple[int, int], dict[tuple[int, int, int], tuple[Sample, float]]] = {}
        # in-order delivery per (writer participant, kind, topic subject, reader)
        self._next: dict[tuple[int, int, int, int], int] = {}
        self._held: dict[tuple[int, int, int, int], dict[int, Msg | None]] = {}
        self.dds_meta_messages = 0
        self.dds_unmatched = 0
        phase = streams.stream("dds.launch").uniform(0, list(range(nsub)), 0, 0)
        self.launch = (phase * d.spdp_initial_period).tolist()
        for p in range(nsub):
            self.k.at(self.launch[p], self._announce, p, 0)
            if d.reliable:
                self.k.at(self.launch[p] + d.heartbeat_period, self._heartbeats, p, 1)

    # ------------------------------------------------------------ threads and hops

    def _cpu(self, p: int, t: float, cost: float) -> float:
        """Serve ``cost`` seconds on participant ``p``'s thread from ``t``; the end time."""
        busy = self.thread[p]
        done = (t if t > busy else busy) + cost
        self.thread[p] = done
        return done

    def _count_meta(self, t: float) -> None:
        if self.warmup <= t < self.end:
            self.dds_meta_messages += 1

    def _send(
        self, src: int, dst: int, kind: int, subj: int, index: int, attempt: int,
        nbytes: int, t: float, fn: Any, args: tuple[Any, ...],
    ) -> None:
        """One packet src → dst leaving ``src``'s thread at ``t``; ``fn(*args)`` on arrival."""
        arr, lost = self.hop(src, True, kind, subj, index, attempt, nbytes, t)
        self.k.at(arr, self._switch, dst, kind, subj, index, attempt, nbytes, lost, fn, args)

    def _switch(
        self, dst: int, kind: int, subj: int, index: int, attempt: int, nbytes: int,
        lost: bool, fn: Any, args: tuple[Any, ...],
    ) -> None:
        if lost:  # the uplink lost it: nothing reaches the reader's link
            fn(False, *args)
            return
        arr, lost2 = self.hop(dst, False, kind, subj, index, attempt, nbytes, self.k.now)
        if lost2:
            fn(False, *args)
        else:
            self.k.at(arr, fn, True, *args)

    # ------------------------------------------------------------ user data

    def wire_bytes(self, payload_bits: int, unicast: bool = True) -> int:
        """Wire bytes of one DATA datagram carrying ``payload_bits``."""
        key = (payload_bits, unicast)
        b = self._data_b.get(key)
        if b is None:
            b = self._data_b[key] = self._frame(data_bytes(payload_bits, unicast))
        return b

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
        """``client`` writes a sample; it goes to every matched reader in ``subscribers``."""
        t = self.k.now
        wk = (client, kind, subject)  # one writer per topic: per-vehicle topics apart
        seq = self._written.get(wk, 0)
        self._written[wk] = seq + 1
        subs = [s for s in subscribers if s in self.matched[client]]
        if len(subs) < len(subscribers) and self.warmup <= t < self.end:
            self.dds_unmatched += len(subscribers) - len(subs)
        if not subs:
            return
        for sub in subs:  # a reader's first sample from this writer starts its order
            self._next.setdefault((client, kind, subject, sub), seq)
        msg = Sample(client, kind, subject, index, payload, payload_bits, tuple(subs), 0, t, t,
                     seq=seq)
        if self.spec.multicast and len(subs) > 1:
            done = self._cpu(client, t, self._w_cost.get(kind, subject, index, 0))
            nbytes = self.wire_bytes(payload_bits, False)
            arr, lost = self.hop(client, True, kind, subject, index, 0, nbytes, done)
            self.k.at(arr, self._fan_out, client, subs, msg, nbytes, lost, done)
            return
        for sub in subs:
            self._send_data(client, sub, msg, 0, t)

    def _reader_subject(self, msg: Msg, sub: int) -> int:
        """Draw subject of ``msg``'s copy to reader ``sub`` (per reader for a broadcast)."""
        return sub if msg.subject == self.server else msg.subject

    def _fan_out(
        self, client: int, subs: list[int], msg: Sample, nbytes: int, lost: bool,
        t_sent: float,
    ) -> None:
        kind, index = msg.kind, msg.index
        for sub in subs:
            ds = self._reader_subject(msg, sub)
            if lost:
                self._on_data(False, client, sub, msg, 0, t_sent)
                continue
            arr, lost2 = self.hop(sub, False, kind, ds, index, 0, nbytes, self.k.now)
            if lost2:
                self._on_data(False, client, sub, msg, 0, t_sent)
            else:
                self.k.at(arr, self._on_data, True, client, sub, msg, 0, t_sent)

    def _send_data(self, client: int, sub: int, msg: Sample, attempt: int, t: float) -> None:
        kind, index = msg.kind, msg.index
        ds = self._reader_subject(msg, sub)
        done = self._cpu(client, t, self._w_cost.get(kind, ds, index, attempt))
        self._send(client, sub, kind, ds, index, attempt, self.wire_bytes(msg.bits), done,
                   self._on_data, (client, sub, msg, attempt, done))

    def _on_data(self, ok: bool, client: int, sub: int, msg: Sample, attempt: int,
                 t_sent: float) -> None:
        kind = msg.kind
        if not ok:
            if self.spec.reliable:
                self._lost.setdefault((client, sub), {})[(kind, msg.seq, attempt)] = (
                    msg, t_sent)
            return
        ds = self._reader_subject(msg, sub)
        cost = self._r_cost.get(kind, ds, msg.index, attempt) + self._dispatch[sub]
        done = self._cpu(sub, self.k.now, cost)
        item = msg.to(sub, ds, t_sent)
        if self.spec.reliable:
            self.k.at(done, self._ordered_ready, (client, kind, msg.subject, sub), msg.seq, item)
        else:
            self.k.at(done, self.deliver, item)

    def _ordered_ready(self, ch: tuple[int, int, int, int], seq: int, item: Msg | None) -> None:
        """Sample ``seq`` (None: a GAP) of channel ``ch`` is ready; deliver what is in order."""
        nxt = self._next[ch]
        if seq < nxt:
            return  # a duplicate of something already delivered or skipped
        held = self._held.setdefault(ch, {})
        held[seq] = item
        while nxt in held:
            it = held.pop(nxt)
            nxt += 1
            if it is not None:
                self.deliver(it)
        self._next[ch] = nxt

    # ------------------------------------------------------------ reliability

    def _heartbeats(self, p: int, j: int) -> None:
        """Writer participant ``p``'s periodic HEARTBEAT ``j`` to every matched reader."""
        t = self.k.now
        meta = self.spec.meta_cost
        readers = self.matched[p] if p == self.server else self.matched[p] & {self.server}
        for r in sorted(readers):
            done = self._cpu(p, t, meta)
            self._count_meta(t)
            self._send(p, r, _HB, r, j, 0, self._hb_b, done, self._on_heartbeat, (p, r, j, done))
        self.k.at(self.launch[p] + (j + 1) * self.spec.heartbeat_period, self._heartbeats,
                  p, j + 1)

    def _on_heartbeat(self, ok: bool, w: int, r: int, j: int, t_hb: float) -> None:
        if not ok:
            return  # the next HEARTBEAT will ask again
        d = self.spec
        done = self._cpu(r, self.k.now, d.meta_cost) + d.heartbeat_response_delay
        self.k.at(done, self._acknack, w, r, j, t_hb)

    def _acknack(self, w: int, r: int, j: int, t_hb: float) -> None:
        t = self.k.now
        lost = self._lost.get((w, r), {})
        nack = [key for key, (_m, ts) in lost.items() if ts < t_hb]
        done = self._cpu(r, t, self.spec.meta_cost)
        self._count_meta(t)
        self._send(r, w, _AN, w, j, 0, self._an_b, done, self._on_acknack, (w, r, nack))

    def _on_acknack(self, ok: bool, w: int, r: int, nack: list[tuple[int, int, int]]) -> None:
        if not ok:
            return
        d = self.spec
        t = self._cpu(w, self.k.now, d.meta_cost) + d.nack_response_delay
        lost = self._lost.get((w, r), {})
        for key in nack:
            item = lost.pop(key, None)
            if item is None:
                continue
            msg, _ts = item
            kind, seq, attempt = key
            written = self._written[(w, kind, msg.subject)]
            if written - seq > d.history_depth or attempt >= self.max_retries:
                self.gave_up += 1  # out of the KEEP_LAST history: the reader gets a GAP
                self._count_meta(t)
                self._send(w, r, _GAP, r, seq, 0, self._an_b, t, self._on_gap,
                           ((w, kind, msg.subject, r), seq, 0))
                continue
            self.retransmissions += 1
            self.k.at(t, self._send_data, w, r, msg, attempt + 1, t)

    def _on_gap(self, ok: bool, ch: tuple[int, int, int, int], seq: int, attempt: int) -> None:
        if not ok:  # a lost GAP: the writer repeats it after the next HEARTBEAT round
            t = self.k.now + self.spec.heartbeat_period
            self.k.at(t, self._send, ch[0], ch[3], _GAP, ch[3], seq, attempt + 1, self._an_b,
                      t, self._on_gap, (ch, seq, attempt + 1))
            return
        done = self._cpu(ch[3], self.k.now, self.spec.meta_cost)
        self.k.at(done, self._ordered_ready, ch, seq, None)

    # ------------------------------------------------------------ discovery

    def _announce(self, p: int, i: int) -> None:
        """SPDP announcement ``i`` of participant ``p`` (multicast to every other)."""
        t = self.k.now
        d = self.spec
        done = self._cpu(p, t, d.meta_cost)
        self._count_meta(t)
        arr, lost = self.hop(p, True, _SPDP, p, i, 0, self._spdp_b, done)
        if not lost:
            self.k.at(arr, self._spdp_copy, p, i)
        if i + 1 < d.spdp_initial_count:
            nxt = self.launch[p] + (i + 1) * d.spdp_initial_period
        else:
            last = self.launch[p] + max(0, d.spdp_initial_count - 1) * d.spdp_initial_period
            nxt = last + (i + 2 - max(1, d.spdp_initial_count)) * d.spdp_period
        self.k.at(nxt, self._announce, p, i + 1)

    def _spdp_copy(self, p: int, i: int) -> None:
        """The switch copies ``p``'s announcement once onto every other link."""
        t = self.k.now
        seen: dict[int, tuple[float, bool]] = {}
        for q in range(self.n + 1):
            if q == p:
                continue
            link = self.link_of[q]
            if link not in seen:
                if link == self.link_of[p]:
                    seen[link] = (t, False)  # same host: the kernel loops it back
                else:
                    seen[link] = self.hop(q, False, _SPDP, p, i, 0, self._spdp_b, t)
            arr, lost = seen[link]
            if not lost:
                self.k.at(arr, self._on_spdp, True, q, p)

    def _on_spdp(self, ok: bool, q: int, p: int) -> None:
        """Participant ``q`` handles ``p``'s announcement; a new one starts SEDP."""
        if not ok:
            return
        d = self.spec
        done = self._cpu(q, self.k.now, d.meta_cost)
        if p in self.heard[q]:
            return
        self.heard[q].add(p)
        if q not in self.heard[p]:  # answer a newcomer with our own announcement
            self._count_meta(done)
            self._send(q, p, _SPDP, q, -1, 0, self._spdp_b, done, self._on_spdp, (p, q))
        self._send_sedp(q, p, done)

    def _send_sedp(self, q: int, p: int, t: float) -> None:
        ent = self.entities[q]
        done = self._cpu(q, t, ent * self.spec.meta_cost)
        self._count_meta(t)
        self._send(q, p, _SEDP, q, p, 0, self._sedp_b[q], done, self._on_sedp, (q, p, 0))

    def _on_sedp(self, ok: bool, q: int, p: int, attempt: int) -> None:
        """``p`` receives ``q``'s endpoint records: ``p``'s writers now match ``q``'s readers."""
        if not ok:  # SEDP is reliable: resent after a heartbeat round
            if attempt < self.max_retries:
                self.retransmissions += 1
                t = self.k.now + self.spec.heartbeat_period
                self.k.at(t, self._resend_sedp, q, p, attempt + 1)
            else:
                self.gave_up += 1
            return
        self._cpu(p, self.k.now, self.entities[q] * self.spec.meta_cost)
        self.matched[p].add(q)

    def _resend_sedp(self, q: int, p: int, attempt: int) -> None:
        done = self._cpu(q, self.k.now, self.entities[q] * self.spec.meta_cost)
        self._send(q, p, _SEDP, q, p, attempt, self._sedp_b[q], done, self._on_sedp,
                   (q, p, attempt))
