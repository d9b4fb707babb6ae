"""core.gcpause.gc_paused: the collector off inside, restored after (also on error),
left off if it was off, and the requested generation collected afterwards."""

from __future__ import annotations

import gc

import pytest

from sigma_des.core.gcpause import gc_paused


def test_paused_inside_restored_after_and_collected_when_asked(monkeypatch: pytest.MonkeyPatch
                                                               ) -> None:
    collected: list[int] = []
    monkeypatch.setattr(gc, "collect", lambda g=2: collected.append(g) or 0)
    assert gc.isenabled()
    with gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled() and collected == []
    with pytest.raises(ValueError), gc_paused(collect=0):
        raise ValueError("x")
    assert gc.isenabled() and collected == [0]


def test_a_collector_off_before_stays_off() -> None:
    gc.disable()
    try:
        with gc_paused(collect=0):
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()
