"""The live server's clock rules are the DES's (issue 9 items 1–2 carried over to live)."""

from __future__ import annotations

from typing import Any

from sigma_des import load
from sigma_des.live.server import LiveServer


class _FakeLoop:
    """Records the times the server asks to be called at; ``t`` is set by the test."""

    def __init__(self) -> None:
        self.t = 0.0
        self.calls: list[float] = []

    def now(self) -> float:
        return self.t

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        self.calls.append(t)


def _server(sets: list[str]) -> tuple[LiveServer, _FakeLoop]:
    srv = object.__new__(LiveServer)  # no broker: only the timing rules are exercised
    srv.sc = load(None, sets)
    loop = _FakeLoop()
    srv.loop = loop  # type: ignore[assignment]
    srv.f_trig = srv.sc.f_trig
    srv._base = (0.0, 0, srv.sc.f_trig)
    srv.trig_time = {}
    return srv, loop


def test_ticks_carry_the_scenario_phases() -> None:
    srv, _ = _server(["nodes=2", "align_phase=0.25", "render_phase=0.5"])
    assert srv._align_time(0) == 0.25 / srv.sc.f_align
    assert srv._align_time(7) == 7.25 / srv.sc.f_align
    assert srv._render_time(3) == 3.5 / srv.sc.f_render


def test_lockstep_triggers_stay_on_the_grid() -> None:
    """1000 barriers completing 1 ms after each trigger: trigger 1000 at exactly 10 s.

    A running sum ``t_k + 1/f`` (the old rule) lands at 9.999999999999831 s instead.
    """
    srv, loop = _server(["nodes=2", "f_trig=100"])
    t_k = 0.0
    for frame in range(1000):
        srv.trig_time[frame] = t_k
        loop.t = t_k + 0.001
        srv.barrier_done(frame)
        t_k = loop.calls[-1]
    assert t_k == 10.0
    assert loop.calls[:3] == [0.01, 0.02, 0.03]


def test_late_barrier_restarts_the_grid() -> None:
    srv, loop = _server(["nodes=2", "f_trig=100"])
    srv.trig_time[0] = 0.0
    loop.t = 0.0375  # the barrier of frame 0 completes late
    srv.barrier_done(0)
    assert loop.calls[-1] == 0.0375
    srv.trig_time[1] = 0.0375
    loop.t = 0.04
    srv.barrier_done(1)
    assert loop.calls[-1] == 0.0375 + 1 / 100
