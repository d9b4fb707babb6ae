"""A first signal that lands in a finalizer (paho's ``Client.__del__``) still ends the run."""

from __future__ import annotations

import gc
import os
import signal
import sys
import time
from typing import Any

import pytest

from sigma_des.live.interrupts import Interrupts


class Finalized:
    """An object whose finalizer receives the signal (as paho's ``Client.__del__`` did)."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # the handler runs here, inside the finalizer


class Failing:
    def __del__(self) -> None:
        raise ValueError("not an interrupt")


def _wait(steps: int = 200) -> int:
    i = 0
    for i in range(steps):  # noqa: B007  (the count shows the wait was not cut)
        time.sleep(0.005)
    return i


def test_a_signal_swallowed_by_a_finalizer_is_delivered_again(
        monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[BaseException] = []

    def hook(u: Any) -> None:  # what Python's own hook would print
        seen.append(u.exc_value)

    gc.collect()  # earlier tests' garbage: its finalizers are not this test's
    monkeypatch.setattr(sys, "unraisablehook", hook)
    with Interrupts() as sig:
        with pytest.raises(KeyboardInterrupt):
            x = Finalized()
            del x  # the KeyboardInterrupt raised in __del__ is swallowed by Python
            gc.collect()
            _wait(1000)  # ... and delivered again 10 ms later: it ends the wait (5 s
            # bound: a loaded test machine may start the timer's thread late)
        assert sig.count == 1 and seen == []  # nothing printed for it
        y = Failing()
        del y  # any other exception of a finalizer is reported as before
        assert [str(e) for e in seen] == ["not an interrupt"]
    assert sys.unraisablehook is hook  # put back


def test_a_second_signal_is_only_noted(capsys: pytest.CaptureFixture[str]) -> None:
    with Interrupts() as sig:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            _wait()
        os.kill(os.getpid(), signal.SIGINT)
        assert _wait() == 199 and sig.count == 2
    assert "SIGINT: noted" in capsys.readouterr().err
