"""The live server runs the DES's clock rules: tick phases, the trigger grid, late barriers.

The server is built as the runner builds it, on a virtual loop and with a client
that only records what is published (no broker): what is checked is what it sends.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sigma_des import load
from sigma_des.live.loop import VirtualLoop
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import Topics, decode_trigger


class _Sent:
    """A client that keeps every published ``(topic, payload)``."""

    def __init__(self, subs: list[tuple[str, int]], on_message: Callable[..., Any]) -> None:
        self.published: list[tuple[str, bytes]] = []
        self.connects = 1

    def publish(self, topic: str, payload: bytes, qos: int) -> None:
        self.published.append((topic, payload))


def _server(sets: list[str], method: str = "none") -> tuple[LiveServer, VirtualLoop, _Sent]:
    loop = VirtualLoop()
    srv = LiveServer(load(None, ["nodes=2", *sets]), method, _Sent, Topics("t"), 1, False,
                     loop=loop)
    assert isinstance(srv.client, _Sent)
    return srv, loop, srv.client


def _triggers(srv: LiveServer, client: _Sent) -> list[tuple[int, float]]:
    """``(frame, t_send)`` of every trigger sent."""
    return [decode_trigger(p)[:2] for t, p in client.published if t == srv.topics.trig]


def test_ticks_carry_the_scenario_phases() -> None:
    srv, loop, _ = _server(["align_phase=0.25", "render_phase=0.5", "warmup=0"])
    f_align, f_render = srv.sc.f_align, srv.sc.f_render
    assert srv.align_time(0) == 0.25 / f_align
    assert srv.align_time(7) == 7.25 / f_align
    srv.start()
    loop.run(until=0.1)
    # the render ticks the collector sampled: at (j + 0.5) / f_render, j = 0, 1, ...
    assert srv.collector.ts["t"] == [(j + 0.5) / f_render for j in range(6)]
    assert srv.align_tick == 6  # (j + 0.25) / 60 < 0.1 for j = 0..5


def test_periodic_triggers_are_on_the_grid() -> None:
    srv, loop, client = _server(["f_trig=100", "duration=11"])
    srv.start()
    loop.run(until=10.0 + 1e-9)
    sent = _triggers(srv, client)
    assert sent[1000] == (1000, 10.0)  # multiplied: a running sum lands at 9.99999999999983
    assert [t for _k, t in sent[:4]] == [0.0, 0.01, 0.02, 0.03]


def _issue_next(srv: LiveServer, loop: VirtualLoop, client: _Sent) -> tuple[int, float]:
    """Run the loop until the next trigger is sent; its ``(frame, t_send)``."""
    n = len(_triggers(srv, client))
    while len(_triggers(srv, client)) == n:
        loop.run(until=loop.now + 0.0005)
    return _triggers(srv, client)[-1]


def test_lockstep_triggers_stay_on_the_grid() -> None:
    """1000 barriers completing 1 ms after each trigger: trigger 1000 at exactly 10 s.

    A running sum ``t_k + 1/f`` (the old rule) lands at 9.999999999999831 s instead.
    """
    srv, loop, client = _server(["f_trig=100", "duration=20"], "lockstep")
    srv.start()
    for frame in range(1000):
        k, t_k = _issue_next(srv, loop, client)
        assert k == frame
        loop.run(until=t_k + 0.001)
        srv.barrier_done(frame)  # what the Lock-Step aligner calls when frame is complete
    assert _issue_next(srv, loop, client) == (1000, 10.0)
    assert [t for _k, t in _triggers(srv, client)[:3]] == [0.0, 0.01, 0.02]


def test_late_barrier_restarts_the_grid() -> None:
    srv, loop, client = _server(["f_trig=100"], "lockstep")
    srv.start()
    _issue_next(srv, loop, client)
    loop.run(until=0.0375)  # the barrier of frame 0 completes late
    srv.barrier_done(0)
    assert _issue_next(srv, loop, client) == (1, 0.0375)
    loop.run(until=0.04)
    srv.barrier_done(1)
    assert _issue_next(srv, loop, client) == (2, 0.0375 + 1 / 100)
