"""Clocks across machines: NTP-style exchanges over the broker, offset and drift per host.

On one machine every live process stamps with one ``time.monotonic()``. Across
machines each host has its own clock ``C_h``; the alignment server's is ``C_s``.
The server measures each host's clock against its own with NTP's four timestamps
(RFC 5905, section 8) carried over MQTT: it sends a *ping* stamped ``t1`` (its
clock) to host ``h``, the host stamps its receipt ``t2`` and its reply ``t3`` (its
clock) and the server stamps the reply's arrival ``t4``. One exchange gives

* the offset ``theta = ((t2 - t1) + (t3 - t4)) / 2`` of ``C_h - C_s`` at the server
  time ``m = (t1 + t4) / 2``,
* the round-trip delay ``delta = (t4 - t1) - (t3 - t2)``; whatever the two one-way
  delays are, the true offset at ``m`` lies within ``theta +- delta / 2``.

Exchanges run before the run (a burst) and periodically during it. A *minimum-RTT
filter* (NTP's clock filter) keeps the exchange with the smallest delay of each
burst of pings, since a short round trip leaves little room for
asymmetry; a least-squares line through the kept offsets gives the offset at a
reference time and the drift: ``C_h - C_s = offset + drift * (C_s - ref)``.

The residual uncertainty is a bound, not a spread: the fitted offset at time ``x`` is
a weighted sum of the kept offsets, ``sum w_i(x) theta_i``, whose weights sum to 1, so
its error is at most ``sum |w_i(x)| delta_i / 2``; that is largest at one end of the
span it is used over (it is convex in ``x``), where :meth:`ClockFit.bound` takes it.
It assumes only a constant drift over the run. :class:`ClockBook` holds the fits of
every host, converts host times to server times and counts every latency that would
be negative after the correction (reported, never clipped).
"""

from __future__ import annotations

import math
import struct
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_DRIFT", "MIN_SPAN", "PING", "PONG", "ClockBook", "ClockFit", "Exchange",
           "SyncClient", "SyncTopics", "fit_clock", "host_clock", "min_rtt_filter", "now_fn"]

#: ping: seq u32, t1 f64 (server clock); pong: seq u32, t1 f64, t2 f64, t3 f64 (host clock)
PING = struct.Struct("<Id")
PONG = struct.Struct("<Iddd")
#: Drift is fitted only over kept exchanges spanning at least this long (s); before, 0.
MIN_SPAN = 2.0
#: Largest drift believed (s/s): NTP's frequency tolerance, 500 ppm; a fit beyond is noise.
MAX_DRIFT = 500e-6


@dataclass(frozen=True)
class Exchange:
    """One NTP-style exchange: ``t1``, ``t4`` on the server's clock, ``t2``, ``t3`` on the
    host's (seconds), and the burst of pings it belongs to (the filter's group)."""

    t1: float
    t2: float
    t3: float
    t4: float
    group: int = 0

    @property
    def offset(self) -> float:
        """``theta``: the host clock minus the server clock at :attr:`mid`."""
        return ((self.t2 - self.t1) + (self.t3 - self.t4)) / 2.0

    @property
    def delay(self) -> float:
        """``delta``: the round trip without the host's own turnaround."""
        return (self.t4 - self.t1) - (self.t3 - self.t2)

    @property
    def mid(self) -> float:
        """The server time the offset refers to."""
        return (self.t1 + self.t4) / 2.0


class SyncTopics:
    """The clock-sync and per-host start topics of run ``run`` (``sd/<run>/sync/h<H>/...``).

    They lie outside ``up/#`` and ``down/...`` so neither the alignment server's client
    nor the hosts' usual subscriptions see them.
    """

    def __init__(self, run: str) -> None:
        self.base = f"sd/{run}/sync"

    def ping(self, host: int) -> str:
        """Server -> host ``host``: a ping."""
        return f"{self.base}/h{host}/ping"

    def go(self, host: int) -> str:
        """Server -> host ``host``: ``go:<t0>`` with ``t0`` on the host's own clock."""
        return f"{self.base}/h{host}/go"

    def pong(self, host: int) -> str:
        """Host ``host`` -> server: the reply."""
        return f"{self.base}/h{host}/pong"

    @property
    def pongs(self) -> str:
        """Every host's replies."""
        return f"{self.base}/+/pong"

    def host_of(self, topic: str) -> int | None:
        """The host of a pong topic, None if it is not one."""
        if not topic.startswith(self.base + "/h") or not topic.endswith("/pong"):
            return None
        h = topic[len(self.base) + 2 : -len("/pong")]
        return int(h) if h.isdigit() else None


def min_rtt_filter(ex: Sequence[Exchange]) -> list[Exchange]:
    """The exchange with the smallest delay of each burst (``group``), in time order."""
    best: dict[int, Exchange] = {}
    for e in ex:
        b = best.get(e.group)
        if b is None or e.delay < b.delay:
            best[e.group] = e
    return sorted(best.values(), key=lambda e: e.mid)


@dataclass(frozen=True)
class ClockFit:
    """``C_h - C_s = offset + drift * (C_s - ref)`` from the kept exchanges.

    Attributes:
        ref: server time the offset refers to (the first kept exchange's ``mid``).
        offset: host minus server clock at ``ref`` (s).
        drift: rate of the offset (s/s; 1e-6 = 1 ppm).
        mids: the kept exchanges' server times.
        half_delays: their ``delta / 2``.
        residual_rms: RMS of the kept offsets about the line (s).
        exchanges: exchanges received.
        rtt_min: smallest round-trip delay seen (s).
    """

    ref: float
    offset: float
    drift: float
    mids: tuple[float, ...]
    half_delays: tuple[float, ...]
    residual_rms: float
    exchanges: int
    rtt_min: float

    def host_time(self, server: float) -> float:
        """The host's clock when the server's reads ``server``."""
        return server + self.offset + self.drift * (server - self.ref)

    def server_time(self, host: float) -> float:
        """The server's clock when the host's reads ``host``."""
        return (host - self.offset + self.drift * self.ref) / (1.0 + self.drift)

    def bound(self, upto: float | None = None) -> float:
        """Worst-case error of the fitted offset over the span of the kept exchanges,
        extended to server time ``upto`` (s): ``max_x sum_i |w_i(x)| delta_i / 2``."""
        x = np.asarray(self.mids)
        hd = np.asarray(self.half_delays)
        ends = [x.min(), x.max()] + ([upto] if upto is not None else [])
        lo, hi = min(ends), max(ends)
        if x.size == 1 or self.drift == 0.0:  # the mean of the kept offsets
            return float(hd.mean())
        xm = x.mean()
        sxx = float(((x - xm) ** 2).sum())
        worst = 0.0
        for at in (lo, hi):
            w = 1.0 / x.size + (at - xm) * (x - xm) / sxx
            worst = max(worst, float((np.abs(w) * hd).sum()))
        return worst


def fit_clock(ex: Sequence[Exchange]) -> ClockFit:
    """Least-squares offset and drift through the minimum-RTT exchanges of ``ex``.

    While the kept exchanges span less than :data:`MIN_SPAN` the drift is 0 (a line
    through points a fraction of a second apart turns millisecond jitter into a drift of
    thousands of ppm); a fitted drift beyond :data:`MAX_DRIFT` is held at that limit
    (the offset then refitted) and is noise.

    Raises:
        ValueError: no exchanges.
    """
    if not ex:
        raise ValueError("no clock exchanges")
    kept = min_rtt_filter(ex)
    x = np.array([e.mid for e in kept])
    y = np.array([e.offset for e in kept])
    ref = float(x[0])
    dx = x - ref
    drift, off = 0.0, float(y.mean())
    if x.size >= 2 and float(np.ptp(dx)) >= MIN_SPAN:
        drift, off = (float(v) for v in np.polyfit(dx, y, 1))
        if abs(drift) > MAX_DRIFT:
            drift = math.copysign(MAX_DRIFT, drift)
            off = float((y - drift * dx).mean())
    resid = y - (off + drift * dx)
    return ClockFit(ref=ref, offset=float(off), drift=float(drift),
                    mids=tuple(x.tolist()), half_delays=tuple(e.delay / 2 for e in kept),
                    residual_rms=float(np.sqrt((resid**2).mean())), exchanges=len(ex),
                    rtt_min=float(min(e.delay for e in ex)))


class ClockBook:
    """Every host's exchanges and current fit; host run times to server run times.

    Host ``h`` runs on its own clock from ``t0_host[h]``, the server's ``t0`` told in its
    clock; a host run time ``tau`` is the host clock ``t0_host[h] + tau``, i.e. the
    server clock :meth:`ClockFit.server_time` of it, minus the server's ``t0``. Fits are
    replaced (not mutated) as exchanges arrive, from the sync client's thread; readers
    on the server's loop see one fit or the next.

    Args:
        hosts: the run's hosts.
    """

    def __init__(self, hosts: int) -> None:
        self.exchanges: list[list[Exchange]] = [[] for _ in range(hosts)]
        self.fits: list[ClockFit | None] = [None] * hosts
        self.t0 = 0.0
        self.t0_host = [0.0] * hosts
        self.negative = [0] * hosts
        self.online: list[list[tuple[float, float]]] = [[] for _ in range(hosts)]
        self.burst = 0  # the current burst of pings (the filter's group)
        self._lock = threading.Lock()

    def new_method(self) -> None:
        """A method starts: its counts start at 0 (exchanges and fits are kept: the hosts'
        clocks are the same from method to method, and a longer span fits drift better)."""
        self.negative = [0] * len(self.fits)
        self.online = [[] for _ in self.fits]

    def add(self, h: int, e: Exchange) -> None:
        """A new exchange with host ``h``: refit."""
        with self._lock:
            self.exchanges[h].append(e)
            self.fits[h] = fit_clock(self.exchanges[h])

    def start(self, t0: float, hosts: Sequence[int]) -> dict[int, float]:
        """Set the server's origin ``t0`` (its clock); return each of ``hosts``' (its clock).

        Raises:
            RuntimeError: a host never answered a ping.
        """
        self.t0 = t0
        for h in hosts:
            f = self.fits[h]
            if f is None:
                raise RuntimeError(f"live host {h} answered no clock exchange")
            self.t0_host[h] = f.host_time(t0)
        return {h: self.t0_host[h] for h in hosts}

    def to_server(self, h: int, tau: float, fit: ClockFit | None = None) -> float:
        """Host ``h``'s run time ``tau`` on the server's run clock (current fit, or ``fit``)."""
        f = fit if fit is not None else self.fits[h]
        assert f is not None
        return f.server_time(self.t0_host[h] + tau) - self.t0

    def latency(self, h: int, t_send_host: float, t_recv: float) -> float:
        """``t_send_host`` (host ``h``'s run time) on the server's clock; a message whose
        corrected send time lies after its receipt ``t_recv`` is counted in
        :attr:`negative` (and kept as it is)."""
        t = self.to_server(h, t_send_host)
        if t > t_recv:
            self.negative[h] += 1
        self.online[h].append((t_send_host, t))
        return t

    def final(self, h: int, tau: NDArray[np.float64]) -> NDArray[np.float64]:
        """Like :meth:`to_server` (for an array) with the fit of every exchange so far."""
        g = fit_clock(self.exchanges[h])
        return (self.t0_host[h] + tau - g.offset + g.drift * g.ref) / (1.0 + g.drift) - self.t0

    def report(self, upto: float) -> dict[str, dict[str, Any]]:
        """Per host: the origin (server clock, s) and the host's offset there (s), drift
        (ppm), the error bound over the run up to run time ``upto`` (s), smallest round
        trip, residual, negative latencies, and how far the states' online correction (the
        fit when each arrived) lies from the fit of the whole run (s)."""
        out: dict[str, dict[str, Any]] = {}
        for h, ex in enumerate(self.exchanges):
            if not ex:
                out[str(h)] = {"exchanges": 0, "negative_latencies": self.negative[h]}
                continue
            f = fit_clock(ex)
            on = np.array(self.online[h]).reshape(-1, 2)
            shift = float(np.abs(self.final(h, on[:, 0]) - on[:, 1]).max()) if on.size else 0.0
            out[str(h)] = {
                "origin_s": self.t0,
                "offset_s": f.host_time(self.t0) - self.t0,
                "drift_ppm": f.drift * 1e6,
                "bound_s": f.bound(self.t0 + upto),
                "residual_rms_s": f.residual_rms,
                "rtt_min_s": f.rtt_min,
                "exchanges": f.exchanges,
                "kept": len(f.mids),
                "negative_latencies": self.negative[h],
                "online_vs_final_max_s": shift,
            }
        return out


def host_clock() -> tuple[float, float]:
    """``(offset, drift)`` a test injects into a host's clock through
    ``SIGMA_DES_TEST_CLOCK_OFFSET`` (s) and ``SIGMA_DES_TEST_CLOCK_DRIFT`` (s/s)."""
    import os

    def num(name: str) -> float:
        v = float(os.environ.get(name, "0") or 0)
        if not math.isfinite(v):
            raise ValueError(f"{name} must be finite")
        return v

    return num("SIGMA_DES_TEST_CLOCK_OFFSET"), num("SIGMA_DES_TEST_CLOCK_DRIFT")


def now_fn(offset: float = 0.0, drift: float = 0.0) -> Any:
    """A monotonic clock (s) running ``drift`` fast and ``offset`` ahead (tests only)."""
    if offset == 0.0 and drift == 0.0:
        return time.monotonic
    return lambda: time.monotonic() * (1.0 + drift) + offset


class SyncClient:
    """The server side of the exchanges: its own MQTT client, pinging every host.

    Pings go out at QoS 0 (a resent ping would carry a stale ``t1``); a lost one is
    simply not an exchange. Replies are stamped (``t4``) in the client's network
    thread as they arrive, not on the server's (possibly busy) loop. During the run a
    thread pings each host every ``interval`` seconds, hosts staggered.

    Args:
        addr: the broker (a :class:`~sigma_des.live.broker.BrokerAddress`).
        run: the run token.
        book: where exchanges go.
        max_inflight: the client's QoS 1 window (0: unlimited).
    """

    def __init__(self, addr: Any, run: str, book: ClockBook, max_inflight: int = 0) -> None:
        from sigma_des.live.loop import Client

        self.topics = SyncTopics(run)
        self.book = book
        self.hosts = len(book.fits)
        self.bad = 0
        self._seq = 0
        self._sent: dict[int, tuple[int, float, int]] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.client = Client(addr, f"{run}-sync", [(self.topics.pongs, 0)], self._on_message,
                             max_inflight)

    def _on_message(self, topic: str, payload: bytes) -> None:
        t4 = time.monotonic()
        h = self.topics.host_of(topic)
        if h is None or h >= self.hosts or len(payload) != PONG.size:
            self.bad += 1
            return
        seq, t1, t2, t3 = PONG.unpack(payload)
        sent = self._sent.pop(seq, None)
        if sent is None or sent[:2] != (h, t1) or not (math.isfinite(t2) and math.isfinite(t3)
                                                       and t3 >= t2):
            self.bad += 1  # not an answer to a ping of ours (or a forged one)
            return
        self.book.add(h, Exchange(t1, t2, t3, t4, sent[2]))

    def ping(self, h: int) -> None:
        """One ping to host ``h``, part of the current burst."""
        self._seq += 1
        t1 = time.monotonic()
        self._sent[self._seq] = (h, t1, self.book.burst)
        self.client.publish(self.topics.ping(h), PING.pack(self._seq, t1), 0)

    def start(self) -> None:
        """Connect (<= 5 s)."""
        self.client.start(timeout=5.0)

    def burst(self, rounds: int, gap: float, timeout: float, hosts: Sequence[int]) -> None:
        """One burst: ``rounds`` pings to each of ``hosts``, ``gap`` s apart; then wait
        (<= ``timeout`` s) until each has answered one."""
        self.book.burst += 1
        for _ in range(rounds):
            for h in hosts:
                self.ping(h)
                time.sleep(gap / max(1, len(hosts)))
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and any(self.book.fits[h] is None for h in hosts):
            time.sleep(0.01)

    def periodic(self, interval: float, rounds: int = 3, gap: float = 0.005) -> None:
        """A burst of ``rounds`` pings ``gap`` s apart to each host every ``interval`` s
        (hosts staggered) until :meth:`stop`."""
        def run() -> None:
            while not self._stop.wait(interval):
                self.book.burst += 1
                for _ in range(rounds):
                    for h in range(self.hosts):
                        self.ping(h)
                        if self._stop.wait(gap / self.hosts):
                            return
        self._thread = threading.Thread(target=run, name="sigma-des-clocksync", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop pinging and disconnect (bounded)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.client.stop()
