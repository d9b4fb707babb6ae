"""The metrics window's CPU mark, taken at its time by a helper process off the loop."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

from sigma_des.live.cpu import CpuMeter
from sigma_des.live.cpumark import MarkAhead
from sigma_des.live.loop import VirtualLoop


def _busy_child(seconds: float) -> subprocess.Popen[bytes]:
    """A process that spins for ``seconds`` (its CPU time grows), then exits."""
    code = f"import time\nt = time.monotonic() + {seconds}\nwhile time.monotonic() < t: pass"
    return subprocess.Popen([sys.executable, "-c", code])


def test_a_mark_ahead_is_taken_at_its_time_and_reads_every_process() -> None:
    """Due 0.4 s ahead: the helper's wall stamp is at or after that time (and soon
    after), the spinning child's CPU grew between a mark taken now and the helper's,
    and this process's loop thread did nothing for it."""
    child = _busy_child(2.0)
    try:
        meter = CpuMeter({"server": os.getpid(), "spin": child.pid})
        meter.helper()
        meter.mark("w0now")
        t0 = time.monotonic()
        meter.mark_ahead("w0", t0, 0.4, VirtualLoop())
        time.sleep(0.5)  # the run goes on past the mark's time
        assert meter.collect(timeout=10.0) == []
        wall, busy, cpu = meter.marks["w0"]
        assert t0 + 0.4 <= wall < t0 + 1.5
        assert cpu["spin"] > meter.marks["w0now"][2]["spin"]  # it spun in between
        assert math.isfinite(busy) and set(meter.runq["w0"]) == {"server", "spin"}
        assert len(meter.threads["w0"]["server"]) == len(meter.threads["w0now"]["server"])
    finally:
        child.kill()
        child.wait()


def test_a_mark_the_run_ended_before_is_cancelled_and_said() -> None:
    """The run stopped (Ctrl-C) before the window opened: the helper is stopped at
    once, the mark is missing (the window's rows NaN) and the warning says why."""
    meter = CpuMeter({"server": os.getpid()})
    meter.mark("w1")
    meter.mark_ahead("w0", time.monotonic(), 60.0, VirtualLoop())
    t = time.monotonic()
    (why,) = meter.collect()
    assert time.monotonic() - t < 5.0
    assert "'w0' not taken (the run ended before it)" in why
    rows = meter.rows({})
    assert math.isnan(rows[0]["cpu_s"]) and math.isnan(rows[0]["window_s"])


def test_a_helper_that_fails_is_reported_not_waited_for() -> None:
    """A helper that dies (killed here) leaves the mark out with its exit status."""
    ahead = MarkAhead({"server": os.getpid()})
    assert ahead.ready  # started, imports done, waiting for its time
    ahead.proc.kill()
    ahead.proc.wait()
    ahead.arm(time.monotonic())  # the request goes nowhere: no error here
    got = ahead.result(timeout=5.0)
    assert isinstance(got, str) and got.startswith("exit -9")


def test_a_helper_slow_to_start_still_delivers_its_mark() -> None:
    """Not waited for at start (``ready_s`` 0): its 'ready' line and its mark are read
    in order whoever reads first, and the mark comes back whole."""
    ahead = MarkAhead({"server": os.getpid()}, ready_s=0.0)
    ahead.arm(time.monotonic() + 0.5)
    got = ahead.result(timeout=10.0)
    assert not isinstance(got, str), got
    (wall, _busy, cpu), runq, threads = got
    assert wall >= ahead.at and set(cpu) == set(runq) == set(threads) == {"server"}
