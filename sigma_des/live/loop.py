"""The event loop every live process runs, and its paho-mqtt client.

A :class:`Loop` is single-threaded: timers (a heap) and an inbox fed by paho's
network thread. Every message is stamped with its receive time in the network
thread (``on_message``) and handled on the loop thread, so the alignment code
never runs concurrently with itself. Times are seconds since the run's start
``t0`` on ``time.monotonic()`` (one clock for every process on one machine).
It is the live mode's :class:`~sigma_des.core.clock.Clock`: the rules the DES runs
on its kernel (trigger, server ticks, node jobs) run on it unchanged, and timers
due at one instant run in the clock's priority order. :class:`VirtualLoop` is the
same dispatch on virtual time (no waiting): the live processes' rules can be run
deterministically in one process, e.g. against the DES (the equivalence test).

:class:`Client` wraps ``paho.mqtt.client.Client`` (``CallbackAPIVersion.VERSION2``,
MQTT 3.1.1): TCP_NODELAY on its socket (no Nagle batching), a configurable QoS 1
in-flight window, resubscription on every (re)connect and reconnect with
exponential backoff (paho's ``reconnect_delay_set``).
"""

from __future__ import annotations

import heapq
import math
import queue
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import paho.mqtt.client as mqtt

from sigma_des.core.clock import ARRIVAL
from sigma_des.core.gcpause import gc_paused
from sigma_des.live.broker import BrokerAddress

__all__ = ["Client", "Loop", "VirtualLoop", "WakeStats"]

_Timer = tuple[float, int, int, Callable[..., Any], tuple[Any, ...]]


@dataclass
class WakeStats:
    """The loop thread's wake-ups in a window, for the per-wake-up CPU demand.

    A *wake-up* is one busy period of the loop thread: from the return of a wait
    (the inbox or a timer due) to the next wait, handling ``k >= 1`` calls. Over the
    wake-ups that start inside ``[lo, hi)`` of the loop's clock it sums the count,
    the calls and the thread's CPU seconds (``time.thread_time``), and the moments a
    least-squares line ``cpu = wake + per_call * k`` needs: a busy period's fixed
    cost (leaving the wait, looking at the timers, going back to wait) is its
    intercept, each call's cost its slope. It also sums the wake-ups' wall time: a
    wake-up's wall time less its CPU is the time the thread was busy but not running
    (waiting for the interpreter lock paho's network thread held, or for a core), the
    part of a process's occupancy that is not CPU.

    Attributes:
        lo, hi: the window (s since the run's start).
        wakes, calls: wake-ups and calls handled in them.
        cpu_s: the loop thread's CPU seconds in them.
        skk, skc: sums of ``k**2`` and ``k * cpu`` over the wake-ups.
        wall_s: the wake-ups' wall seconds (``time.monotonic``), from the return of
            the wait to the next wait.
    """

    lo: float = math.inf
    hi: float = math.inf
    wakes: int = 0
    calls: int = 0
    cpu_s: float = 0.0
    skk: float = 0.0
    skc: float = 0.0
    wall_s: float = 0.0

    def add(self, k: int, cpu: float, wall: float = 0.0) -> None:
        """One wake-up of ``k`` calls that took ``cpu`` thread CPU seconds in ``wall``
        seconds."""
        self.wakes += 1
        self.wall_s += wall
        self.calls += k
        self.cpu_s += cpu
        self.skk += k * k
        self.skc += k * cpu

    def line(self) -> tuple[float, float]:
        """``(wake, per_call)``: the least-squares intercept and slope of a wake-up's
        CPU against its calls; NaN when the calls do not vary (not identifiable)."""
        n = self.wakes
        den = n * self.skk - self.calls * self.calls
        if n < 2 or den <= 0:
            return math.nan, math.nan
        slope = (n * self.skc - self.calls * self.cpu_s) / den
        return (self.cpu_s - slope * self.calls) / n, slope

    def as_dict(self) -> dict[str, float]:
        """The sums (a host's end-of-run stats; sums of several loops pool by adding)."""
        return {"wakes": self.wakes, "calls": self.calls, "cpu_s": self.cpu_s,
                "skk": self.skk, "skc": self.skc, "wall_s": self.wall_s}

    @classmethod
    def pooled(cls, parts: list[dict[str, Any]]) -> WakeStats:
        """The sums of several loops' :meth:`as_dict` (one line fitted to all of them)."""
        out = cls()
        for d in parts:
            out.wakes += int(d["wakes"])
            out.calls += int(d["calls"])
            out.cpu_s += float(d["cpu_s"])
            out.skk += float(d["skk"])
            out.skc += float(d["skc"])
            out.wall_s += float(d.get("wall_s", math.nan))  # NaN: a loop before wall_s
        return out


class Loop:
    """Timers plus an inbox, run on one thread.

    Args:
        t0: ``time.monotonic()`` at the run's start.

    Attributes:
        wake: the wake-ups of the metrics window (:class:`WakeStats`; set its ``lo``
            and ``hi`` to count them).
    """

    def __init__(self, t0: float) -> None:
        self.t0 = t0
        self._heap: list[_Timer] = []
        self._seq = 0
        self.inbox: queue.SimpleQueue[tuple[Callable[..., Any], tuple[Any, ...]]] = (
            queue.SimpleQueue()
        )
        self.stopped = False
        self.handled = 0
        self.wake = WakeStats()

    @property
    def now(self) -> float:
        """Seconds since the run's start."""
        return time.monotonic() - self.t0

    def call_at(self, t: float, fn: Callable[..., Any], *args: Any,
                priority: int = ARRIVAL) -> None:
        """Run ``fn(*args)`` on the loop thread at time ``t`` (loop thread only); calls
        due at one time run by ``priority``, then in the order they were made."""
        self._seq += 1
        heapq.heappush(self._heap, (t, priority, self._seq, fn, args))

    def head_is(self, fn: Callable[..., Any]) -> bool:
        """True if the next timer due is a call of ``fn``."""
        return bool(self._heap) and self._heap[0][3] == fn

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` on the loop thread soon (thread-safe)."""
        self.inbox.put((fn, args))

    def stop(self) -> None:
        """Leave :meth:`run` after the current handler."""
        self.stopped = True

    def run(self, until: float) -> None:
        """Process timers and inbox until :meth:`stop` or time ``until`` (s since t0).

        Python's cyclic garbage collector is paused during the run (reference counting
        still frees everything that is not a cycle; the processes collect between
        runs): a full collection over what the process's earlier runs left stalled a
        live host for 100-130 ms in the fourth method's run, a
        pause no real simulator node has."""
        with gc_paused():
            self._run(until)

    def _run(self, until: float) -> None:
        heap = self._heap
        inbox = self.inbox
        wake = self.wake
        cpu = time.thread_time
        mono = time.monotonic  # wall time of a wake-up (``now`` may be a corrected clock)
        k = 0  # calls of the current wake-up
        c0 = cpu()
        m0 = mono()
        t_wake = self.now
        while not self.stopped:
            now = self.now
            if now >= until:
                break
            while heap and heap[0][0] <= now and not self.stopped:
                _t, _p, _s, fn, args = heapq.heappop(heap)
                fn(*args)
                k += 1
            if k and wake.lo <= t_wake < wake.hi:  # a wake-up ends: the thread waits
                wake.add(k, cpu() - c0, mono() - m0)
            wait = min(until, heap[0][0] if heap else until) - self.now
            try:
                fn, args = inbox.get(timeout=min(0.05, max(wait, 0.0)))
            except queue.Empty:
                k = 0
                c0 = cpu()
                m0 = mono()
                t_wake = self.now
                continue
            c0 = cpu()
            m0 = mono()
            t_wake = self.now
            fn(*args)
            self.handled += 1
            k = 1
            for _ in range(256):  # drain what is there before looking at timers again
                try:
                    fn, args = inbox.get_nowait()
                except queue.Empty:
                    break
                fn(*args)
                self.handled += 1
                k += 1
        if k and wake.lo <= t_wake < wake.hi:
            wake.add(k, cpu() - c0, mono() - m0)


class VirtualLoop(Loop):
    """A :class:`Loop` on virtual time: timers run in order, no waiting, one thread.

    :meth:`post` (a message handed over by a transport) runs at the current
    virtual time, after the calls already due then, as the real loop's inbox does.

    Args:
        t0: the virtual time to start at (s).
    """

    def __init__(self, t0: float = 0.0) -> None:
        super().__init__(0.0)
        self._now = t0

    @property
    def now(self) -> float:
        """The virtual time (s)."""
        return self._now

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` now, after what is already due now."""
        self.handled += 1
        self.call_at(self._now, fn, *args)

    def run(self, until: float) -> None:
        """Run every call due before ``until`` (none at exactly ``until``), in order."""
        heap = self._heap
        while heap and heap[0][0] < until and not self.stopped:
            t, _p, _s, fn, args = heapq.heappop(heap)
            self._now = max(self._now, t)
            fn(*args)
        if not self.stopped:
            self._now = max(self._now, until)


class Client:
    """One paho-mqtt client of a live process.

    Args:
        addr: broker address and credentials.
        client_id: MQTT client id.
        subscriptions: ``(topic, qos)`` pairs, (re)subscribed on every connect.
        on_message: called in paho's thread with ``(topic, payload)``.
        max_inflight: QoS 1 messages in flight before paho queues (0 = unlimited).
    """

    def __init__(
        self,
        addr: BrokerAddress,
        client_id: str,
        subscriptions: list[tuple[str, int]],
        on_message: Callable[[str, bytes], None],
        max_inflight: int = 0,
    ) -> None:
        c = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=client_id,
            protocol=mqtt.MQTTv311,
            clean_session=True,
        )
        if addr.username:
            c.username_pw_set(addr.username, addr.password)
        if addr.tls_ca:  # TLS, the broker's certificate checked against this CA and its name
            import ssl

            c.tls_set_context(ssl.create_default_context(cadata=addr.tls_ca))
        c.max_inflight_messages_set(max_inflight if max_inflight > 0 else 65535)
        c.max_queued_messages_set(0)
        c.reconnect_delay_set(min_delay=1, max_delay=2)
        self.addr = addr
        self.subscriptions = subscriptions
        self.connects = 0
        self.disconnects = 0
        self.refused: str = ""
        self._handler = on_message
        c.on_socket_open = self._nodelay
        c.on_connect = self._on_connect
        c.on_disconnect = self._on_disconnect
        c.on_message = self._on_message
        self.mqtt = c

    @staticmethod
    def _nodelay(client: mqtt.Client, userdata: Any, sock: Any) -> None:
        if isinstance(sock, socket.socket):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, rc: Any,
                    props: Any) -> None:
        if rc.is_failure:
            self.refused = str(rc)
            return
        self.connects += 1
        if self.subscriptions:
            client.subscribe(self.subscriptions)

    def _on_disconnect(self, client: mqtt.Client, userdata: Any, flags: Any, rc: Any,
                       props: Any) -> None:
        self.disconnects += 1

    def _on_message(self, client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        self._handler(msg.topic, bytes(msg.payload))

    def start(self, timeout: float = 5.0) -> None:
        """Connect and start paho's network thread; wait (bounded) for the CONNACK.

        Raises:
            ConnectionError: refused (e.g. wrong credentials) or no answer in ``timeout``.
        """
        try:
            self.mqtt.connect(self.addr.host, self.addr.port, keepalive=5)
        except OSError as e:  # refused, unreachable, a TLS certificate that does not verify
            raise ConnectionError(f"MQTT connect to {self.addr.host}:{self.addr.port}: "
                                  f"{e}") from None
        self.mqtt.loop_start()
        deadline = time.monotonic() + timeout
        while self.connects == 0 and time.monotonic() < deadline:
            if self.refused:
                break
            time.sleep(0.005)
        if self.connects == 0:
            self.stop()
            why = self.refused or f"no CONNACK in {timeout} s"
            raise ConnectionError(f"MQTT connect to {self.addr.host}:{self.addr.port}: {why}")

    def publish(self, topic: str, payload: bytes, qos: int) -> None:
        """Publish (thread-safe; while disconnected paho queues QoS 1 messages)."""
        self.mqtt.publish(topic, payload, qos=qos)

    def stop(self) -> None:
        """Disconnect and stop the network thread."""
        try:
            self.mqtt.disconnect()
        finally:
            self.mqtt.loop_stop()
