"""The live loop's wake-up accounting (live/loop.py ``WakeStats``): the least-squares
line recovered exactly, and a real :class:`Loop` counting its busy periods."""

from __future__ import annotations

import math
import time

import pytest

from sigma_des.live.loop import Loop, WakeStats


def test_line_recovers_a_known_wake_and_per_call_cost_exactly() -> None:
    w = WakeStats(lo=0.0, hi=1.0)
    for k in (1, 1, 2, 4, 7):
        w.add(k, 60e-6 + 15e-6 * k)
    wake, per_call = w.line()
    assert wake == pytest.approx(60e-6, rel=1e-9)
    assert per_call == pytest.approx(15e-6, rel=1e-9)
    assert (w.wakes, w.calls) == (5, 15)
    # pooled sums of two loops fit one line to both
    v = WakeStats()
    v.add(3, 60e-6 + 45e-6)
    both = WakeStats.pooled([w.as_dict(), v.as_dict()])
    assert both.line() == pytest.approx((60e-6, 15e-6), rel=1e-9)


def test_line_is_not_identifiable_when_the_calls_do_not_vary() -> None:
    w = WakeStats()
    for _ in range(4):
        w.add(2, 1e-4)
    assert all(math.isnan(x) for x in w.line())
    assert all(math.isnan(x) for x in WakeStats().line())


def test_a_real_loop_counts_its_busy_periods_inside_the_window() -> None:
    """Three posts waiting when the loop starts are one wake-up of three calls."""
    loop = Loop(time.monotonic())
    loop.wake.lo, loop.wake.hi = 0.0, math.inf
    for x in "abc":
        loop.post(print, x)
    loop.run(until=0.05)
    assert (loop.wake.wakes, loop.wake.calls) == (1, 3)


def test_wake_ups_before_the_window_are_not_counted() -> None:
    """A timer due at once and three posts run before the window opens (not counted);
    the timer due inside it is one wake-up of one call."""
    loop = Loop(time.monotonic())
    loop.wake.lo, loop.wake.hi = 0.02, math.inf
    got: list[str] = []
    loop.call_at(0.0, got.append, "early")  # runs in the first wake-up (starts before lo)
    loop.call_at(0.06, got.append, "timer")
    for x in "abc":
        loop.post(got.append, x)
    loop.run(until=0.1)
    assert got == ["early", "a", "b", "c", "timer"]
    assert (loop.wake.wakes, loop.wake.calls) == (1, 1)  # the early wake-up is outside
    assert loop.wake.cpu_s > 0.0
    assert loop.handled == 3


def test_the_cyclic_collector_is_paused_during_a_run_and_restored() -> None:
    """A live loop runs with Python's cyclic GC paused (a full collection stalled a live
    host 100-130 ms) and restores it afterwards, also when it was off before."""
    import gc

    seen: list[bool] = []
    loop = Loop(time.monotonic())
    loop.post(lambda: seen.append(gc.isenabled()))
    assert gc.isenabled()
    loop.run(until=0.02)
    assert seen == [False] and gc.isenabled()
    gc.disable()
    try:
        Loop(time.monotonic()).run(until=0.01)
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_wall_time_is_summed_and_pooled_and_missing_wall_pools_to_nan() -> None:
    w = WakeStats()
    w.add(1, 50e-6, 80e-6)
    w.add(2, 70e-6, 0.5e-3)
    assert w.wall_s == pytest.approx(0.58e-3, rel=1e-12)
    v = WakeStats()
    v.add(1, 40e-6, 40e-6)
    assert WakeStats.pooled([w.as_dict(), v.as_dict()]).wall_s == pytest.approx(0.62e-3)
    old = {k: x for k, x in v.as_dict().items() if k != "wall_s"}  # a host before wall_s
    assert math.isnan(WakeStats.pooled([w.as_dict(), old]).wall_s)


def test_a_wake_up_that_waits_without_cpu_counts_the_wait_as_wall_not_cpu() -> None:
    """A call that sleeps 20 ms (the thread busy but not running, as when it waits for
    the interpreter lock) adds ~20 ms of wall time and almost no CPU."""
    loop = Loop(time.monotonic())
    loop.wake.lo, loop.wake.hi = 0.0, math.inf
    loop.post(time.sleep, 0.02)
    loop.run(until=0.1)
    assert loop.wake.wakes == 1
    assert loop.wake.wall_s >= 0.02
    assert loop.wake.cpu_s < 0.01
