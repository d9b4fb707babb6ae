"""The live run's start: trigger 0 at the time origin, not a pump step after it."""

from __future__ import annotations

import pytest

from sigma_des.live import runner


class _Clock:
    """A monotonic clock that moves only when the server's loop is pumped."""

    def __init__(self, overshoot: float) -> None:
        self.t = 100.0
        self.steps: list[float] = []
        self.overshoot = overshoot

    def monotonic(self) -> float:
        return self.t

    def pump(self, _srv: object, seconds: float) -> None:
        self.steps.append(seconds)
        self.t += seconds + self.overshoot


@pytest.mark.parametrize("overshoot", [0.0, 0.001])
def test_idle_until_never_pumps_past_the_target(monkeypatch: pytest.MonkeyPatch,
                                                overshoot: float) -> None:
    clock = _Clock(overshoot)
    monkeypatch.setattr(runner, "time", clock)
    monkeypatch.setattr(runner, "_pump", clock.pump)
    runner._idle_until(object(), 100.05)
    # steps of PUMP_STEP while more is left, then exactly the rest (the old loop pumped a
    # whole 0.02 s step past the origin: 100.06)
    assert clock.steps[:2] == [runner.PUMP_STEP, runner.PUMP_STEP]
    assert all(s <= runner.PUMP_STEP for s in clock.steps)
    assert 100.05 - 1e-12 <= clock.t <= 100.05 + overshoot + 1e-12
    assert len(clock.steps) == 3


def test_idle_until_a_past_time_pumps_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = _Clock(0.0)
    monkeypatch.setattr(runner, "time", clock)
    monkeypatch.setattr(runner, "_pump", clock.pump)
    runner._idle_until(object(), 99.0)
    assert clock.steps == []
