"""Access links and transports of the modelled network (docs/concepts/model.md, "Network").

Every client (physics node ``0..n-1``, and the server ``n`` that hosts the
interface, the alignment server and the renderer) reaches the broker over its
host's access link; nodes on one host share that link. A packet's hop time =
FIFO serialization on the link direction + base latency (+ fault delay); it is
lost with the link's loss model. Every random number is drawn by ``(kind,
subject, index, attempt)`` from a stream named after the link class and
direction, so results do not depend on event order.

Transports: ``datagram`` (a lost packet is gone) and ``stream`` (per-connection
in-order delivery; a lost segment is resent after an RTO doubling on each try,
holding back everything behind it: :mod:`sigma_des.net.resend`). MQTT on top of this is in
:mod:`sigma_des.net.network`, the broker in :mod:`sigma_des.net.broker`.

This module takes the net layer's own :class:`~sigma_des.net.spec.NetSetup`
(specs, topology, metrics window, link faults), never the scenario.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache, Sampler
from sigma_des.core.rng import RandomStreams, Stream
from sigma_des.core.sim import Kernel
from sigma_des.net.latency import Dist
from sigma_des.net.loss import LossProcess
from sigma_des.net.message import Msg
from sigma_des.net.resend import stream_backoff
from sigma_des.net.spec import NetSetup

__all__ = ["LinkDir", "Links", "dist_cache"]



class LinkDir:
    """One direction of one access link: FIFO serialization and byte counts."""

    __slots__ = ("busy", "bits_per_s", "sec_per_byte", "bytes", "packets", "name")

    def __init__(self, name: str, mbps: float) -> None:
        self.name = name
        self.busy = 0.0
        self.bits_per_s = mbps * 1e6
        self.sec_per_byte = 8.0 / self.bits_per_s
        self.bytes = 0
        self.packets = 0

    def carried(self, nbytes: int, packets: int, busy: float) -> None:
        """Traffic serialized elsewhere (the compiled core): counted here, busy until ``busy``
        at the latest."""
        self.bytes += nbytes
        self.packets += packets
        self.busy = max(self.busy, busy)


class _Conn:
    """One direction of one client's stream connection (in-order delivery)."""

    __slots__ = ("next_seq", "next_deliver", "pending", "lost")

    def __init__(self) -> None:
        self.next_seq = 0
        self.next_deliver = 0
        #: segments lost and not yet arrived nor given up (awaiting a resend)
        self.lost = 0
        #: segments arrived out of order, by sequence number (None: given up)
        self.pending: dict[int, _Segment | None] = {}


@dataclass(slots=True, eq=False)
class _Segment:
    """One message sent as stream segment ``seq`` of connection ``conn``."""

    conn: _Conn
    seq: int
    m: Msg
    up: bool
    nbytes: int
    on_arrive: Callable[[Msg], None]


class Links:
    """Link directions, per-hop draws and the transports of ``n`` nodes plus the server.

    Args:
        kernel: the SimPy glue.
        setup: the net's specs, topology, metrics window and link faults.
        streams: root random streams.
    """

    def __init__(self, kernel: Kernel, setup: NetSetup, streams: RandomStreams) -> None:
        self.k = kernel
        self.setup = setup
        topo = setup.topology
        hosts = topo.hosts
        self.n = topo.nodes
        self.server = topo.server
        self.warmup = setup.warmup
        self.end = setup.end  # traffic leaving after the run is not counted
        net = setup.net
        self.datagram = net.transport == "datagram"
        self.rto = net.rto
        self.max_retries = net.max_retries
        # link index per client: hosts 0..H-1, the server's link is H
        self.link_of = topo.link_of
        nsub = self.n + 1
        self.up: list[LinkDir] = []
        self.down: list[LinkDir] = []
        for h in range(hosts + 1):
            spec = net.host_link if h < hosts else net.server_link
            name = f"host{h}" if h < hosts else "server"
            self.up.append(LinkDir(f"{name}.up", spec.bandwidth_mbps))
            self.down.append(LinkDir(f"{name}.down", spec.bandwidth_mbps))
        self._lat: dict[tuple[bool, bool], DrawCache] = {}
        self._u: dict[tuple[bool, bool], DrawCache] = {}
        self._loss: dict[tuple[bool, bool, int], LossProcess] = {}
        for is_server, spec in ((False, net.host_link), (True, net.server_link)):
            for up in (True, False):
                tag = f"{'server' if is_server else 'host'}.{'up' if up else 'down'}"
                self._lat[is_server, up] = dist_cache(nsub, spec.latency_of(up), streams,
                                                      f"lat.{tag}")
                ust = streams.stream(f"lossu.{tag}")
                self._u[is_server, up] = DrawCache(nsub, _uniform_sampler(ust), blockable=True,
                                                    uniforms=(ust.key, None))
                for h in range(hosts + 1):
                    if (h == hosts) == is_server:
                        self._loss[is_server, up, h] = LossProcess(
                            spec.loss, streams.stream(f"ge.{tag}"), h
                        )
        self._conns: dict[tuple[int, bool], _Conn] = {}
        self.retransmissions = 0
        self.gave_up = 0
        # degrade faults per link: (start, end, extra_delay, extra_loss)
        self._degrade: dict[int, list[tuple[float, float, float, float]]] = {}
        for f in setup.degrades:
            self._degrade.setdefault(f.host, []).append(
                (f.start, f.end, f.extra_delay, f.extra_loss)
            )
        self.forced_drops = setup.drops
        self._ups = [self.up[h] for h in self.link_of]
        self._downs = [self.down[h] for h in self.link_of]
        self._cls = [0] * self.n + [1]
        self._lat_l = [[self._lat[c, False], self._lat[c, True]] for c in (False, True)]
        self._u_l = [[self._u[c, False], self._u[c, True]] for c in (False, True)]
        self._in_order: list[list[bool]] = []
        for _c, spec in ((False, net.host_link), (True, net.server_link)):
            calm = (spec.loss.model == "bernoulli" and spec.loss.p == 0.0
                    and not self._degrade and not self.forced_drops)
            self._in_order.append([calm and spec.latency_of(up).dist == "constant"
                                   for up in (False, True)])
        self._p_const: list[list[float | None]] = []
        for c, spec in ((False, net.host_link), (True, net.server_link)):
            dyn = spec.loss.model != "bernoulli" or (
                bool(self._degrade) if not c else hosts in self._degrade
            )
            self._p_const.append([None if dyn else spec.loss.p] * 2)

    # ------------------------------------------------------------ one hop

    def hop(
        self,
        client: int,
        up: bool,
        kind: int,
        subject: int,
        index: int,
        attempt: int,
        nbytes: int,
        t: float,
    ) -> tuple[float, bool]:
        """Transmit one packet on ``client``'s access link at time ``t``.

        Returns:
            (arrival time at the far end, lost?)
        """
        ld = (self._ups if up else self._downs)[client]
        busy = ld.busy
        done = (t if t > busy else busy) + nbytes * ld.sec_per_byte
        ld.busy = done
        if self.warmup <= t < self.end:
            ld.bytes += nbytes
            ld.packets += 1
        cls = self._cls[client]
        lat = self._lat_l[cls][up].get(kind, subject, index, attempt)
        p = self._p_const[cls][up]
        extra = 0.0
        if p is None:
            p, extra = self._loss_at(client, up, t)
        lost = p > 0.0 and self._u_l[cls][up].get(kind, subject, index, attempt) < p
        if (
            self.forced_drops
            and not up
            and attempt == 0
            and (kind, subject, index) in self.forced_drops
        ):
            lost = True
        return done + lat + extra, lost

    def count_packet(self, client: int, up: bool, nbytes: int, t: float) -> None:
        """Serialize and count a packet whose arrival does not matter (stream PUBACKs)."""
        ld = (self._ups if up else self._downs)[client]
        busy = ld.busy
        ld.busy = (t if t > busy else busy) + nbytes * ld.sec_per_byte
        if self.warmup <= t < self.end:
            ld.bytes += nbytes
            ld.packets += 1

    def _loss_at(self, client: int, up: bool, t: float) -> tuple[float, float]:
        """Time-dependent loss probability and extra delay (Gilbert–Elliott, faults)."""
        link = self.link_of[client]
        proc = self._loss[client == self.server, up, link]
        spec = proc.spec
        if spec.model == "bernoulli":
            p = spec.p
        else:
            p = spec.loss_bad if bool(proc.bad_state(t)[0]) else spec.loss_good
        extra = 0.0
        for a, b, d, q in self._degrade.get(link, ()):
            if a <= t < b:
                extra += d
                p = 1.0 - (1.0 - p) * (1.0 - q)
        return p, extra

    # ------------------------------------------------------------ transport

    def transmit(
        self, m: Msg, up: bool, nbytes: int, on_arrive: Callable[[Msg], None]
    ) -> tuple[float, bool]:
        """Send ``m`` (``nbytes`` on the wire, at ``m.t_sent``) on its client's link with the
        configured transport; ``on_arrive(m)`` runs at its application-level arrival.
        Returns (first-try arrival, first-try lost)."""
        t = m.t_sent
        client = m.client
        arr, lost = self.hop(client, up, m.kind, m.subject, m.index, m.attempt, nbytes, t)
        if self.datagram or self._in_order[self._cls[client]][up]:
            # a stream on a lossless constant-latency link is already in order (FIFO
            # serialization + equal latency): the in-order bookkeeping would change nothing
            if not lost:
                self.k.at(arr, on_arrive, m)
            return arr, lost
        conn = self._conns.get((client, up))
        if conn is None:
            conn = self._conns[client, up] = _Conn()
        seg = _Segment(conn, conn.next_seq, m, up, nbytes, on_arrive)
        conn.next_seq += 1
        self._stream_try(seg, m.attempt, t, arr, lost)
        return arr, lost

    def _stream_try(self, seg: _Segment, attempt: int, t: float, arr: float,
                    lost: bool) -> None:
        """Try ``attempt`` of stream segment ``seg`` sent at ``t``: in order on arrival,
        or resent after the (doubling) RTO, or given up after ``max_retries``."""
        if not lost:
            self.k.at(arr, self._stream_arrive, seg, True, attempt)
            return
        if attempt == 0:
            seg.conn.lost += 1
        if attempt >= self.max_retries:
            self.gave_up += 1
            self.k.at(t, self._stream_arrive, seg, False, attempt)
            return
        self.retransmissions += 1
        self.k.at(t + stream_backoff(self.rto, attempt), self._stream_retry, seg, attempt + 1)

    def _stream_retry(self, seg: _Segment, attempt: int) -> None:
        t = self.k.env.now
        m = seg.m
        arr, lost = self.hop(m.client, seg.up, m.kind, m.subject, m.index, attempt, seg.nbytes,
                             t)
        self._stream_try(seg, attempt, t, arr, lost)

    def _stream_arrive(self, seg: _Segment, arrived: bool, attempt: int) -> None:
        """Segment ``seg`` arrived on try ``attempt`` (or was given up): deliver what is
        now in order. A downlink segment arriving on a resend, or held behind a gap
        while a segment of its connection awaits a resend, is announced to its receiver
        first (:meth:`read_held`)."""
        conn = seg.conn
        conn.pending[seg.seq] = seg if arrived else None
        if attempt > 0 or not arrived:
            conn.lost -= 1
        if arrived and not seg.up and (
                attempt > 0 or (conn.lost > 0 and seg.seq != conn.next_deliver)):
            self.read_held(seg.m, attempt > 0)
        while conn.next_deliver in conn.pending:
            item = conn.pending.pop(conn.next_deliver)
            conn.next_deliver += 1
            if item is not None:
                item.on_arrive(item.m)

    def read_held(self, m: Msg, resent: bool) -> None:
        """Hook: the copy ``m`` reaches its receiver now, held behind a lost segment of
        its connection (the transport gives it to the receiver when the gap is filled)
        or arriving on a resend (``resent``). Nothing here; the network's CPU stage
        overrides it."""

    def links(self) -> list[LinkDir]:
        """All link directions (uplinks then downlinks)."""
        return self.up + self.down

    def carried(
        self,
        nbytes: NDArray[np.int64],
        packets: NDArray[np.int64],
        busy: NDArray[np.float64],
        retransmissions: int,
        gave_up: int,
    ) -> None:
        """Count traffic carried elsewhere (the compiled core) on these links.

        Args:
            nbytes: wire bytes per direction (0 down, 1 up) and link, in the metrics window.
            packets: packets, likewise.
            busy: per direction and link, when its serialization is free again.
            retransmissions: packets sent again after a loss.
            gave_up: packets given up after the last retry.
        """
        for d, dirs in ((1, self.up), (0, self.down)):
            for k, ld in enumerate(dirs):
                ld.carried(int(nbytes[d, k]), int(packets[d, k]), float(busy[d, k]))
        self.retransmissions += retransmissions
        self.gave_up += gave_up

    # ------------------------------------------------------------ draw tables

    def latency_draws(self, is_server: bool, up: bool) -> DrawCache:
        """Base-latency draws of the server's (or the hosts') link, one direction.

        Read-only use (the compiled core fills its tables from it): drawing from it
        is keyed by ``(kind, subject, index, attempt)``, so reading does not change
        any result.
        """
        return self._lat[is_server, up]

    def loss_process(self, is_server: bool, up: bool, link: int) -> LossProcess:
        """The loss process (Gilbert–Elliott chain) of access link ``link``, one direction.

        Read-only use, as :meth:`latency_draws`: its chain state is a pure function of
        the slot, so asking about any time does not change any result.
        """
        return self._loss[is_server, up, link]

    def loss_draws(self, is_server: bool, up: bool) -> DrawCache:
        """Uniform loss draws of the server's (or the hosts') link, one direction
        (a packet is lost when its draw is below the loss probability)."""
        return self._u[is_server, up]


def dist_cache(n: int, dist: Dist, streams: RandomStreams, name: str) -> DrawCache:
    """Draws of ``dist`` for ``n`` subjects from the stream ``name``, keyed by
    ``(kind, subject, index, attempt)`` (a constant distribution needs no draws)."""
    st = streams.stream(name)
    const = dist.value if dist.dist == "constant" else None
    return DrawCache(n, lambda s, k, i, a: dist.sample(st, k, s, i, a), constant=const,
                     blockable=True, uniforms=(st.key, dist.quantile))


def _uniform_sampler(st: Stream) -> Sampler:
    def sample(s: NDArray[np.int64], k: int, i: int, a: int) -> NDArray[np.float64]:
        return st.uniform(k, s, i, a)

    return sample
