"""Signals during a live run: the first SIGINT, SIGTERM or SIGHUP stops it, later ones wait.

The run's clean-up is bounded and keeps what finished, so a second Ctrl-C must not cut
it short: :class:`Interrupts` raises :class:`KeyboardInterrupt` once and only notes the
rest. A first signal that lands inside a finalizer (paho's ``Client.__del__``), where
Python prints and swallows the exception, is delivered again at once: it still ends
the run.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["Interrupts"]


class Interrupts:
    """SIGINT, SIGTERM and SIGHUP raise :class:`KeyboardInterrupt` once; later ones are
    noted on stderr and ignored (what follows is bounded clean-up that keeps results).

    A context manager; a no-op off the main thread or when already installed.

    Attributes:
        count: signals received so far.
    """

    SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                    if hasattr(signal, n))
    _active: Interrupts | None = None

    def __init__(self) -> None:
        self.count = 0
        self._old: dict[int, Any] = {}
        self._hold = False
        self._pending = False
        self._old_hook: Any = None
        self._first = signal.SIGINT

    def _handle(self, signum: int, frame: Any) -> None:
        self.count += 1
        if self.count == 1:
            self._first = signal.Signals(signum)
            if self._hold:
                self._pending = True
                return
            raise KeyboardInterrupt
        print(f"sigma-des: {signal.Signals(signum).name}: noted; finishing the clean-up "
              "and writes first (keeping what finished)", file=sys.stderr, flush=True)

    @contextmanager
    def held(self) -> Iterator[None]:
        """A first signal during the block is raised at its end (writing is not cut)."""
        self._hold = True
        try:
            yield
        finally:
            self._hold = False
            if self._pending:
                self._pending = False
                raise KeyboardInterrupt

    def _unraisable(self, u: Any) -> None:
        """``sys.unraisablehook``: the first signal's KeyboardInterrupt was swallowed by a
        finalizer: send the signal again 10 ms later, once the finalizer and this hook
        have returned (should it land in a finalizer again, this repeats)."""
        if isinstance(u.exc_value, KeyboardInterrupt) and self.count == 1:
            import os
            import threading

            self.count = 0
            threading.Timer(0.01, os.kill, (os.getpid(), self._first)).start()
            return
        self._old_hook(u)

    def mask(self) -> None:
        """From now on, signals are noted and ignored (e.g. while writing results)."""
        self.count = max(self.count, 1)

    def __enter__(self) -> Interrupts:
        import threading

        if Interrupts._active is not None:
            return Interrupts._active
        if threading.current_thread() is threading.main_thread():
            # a signal ignored when we started (nohup, a background job) stays ignored
            self._old = {s: signal.signal(s, self._handle) for s in self.SIGNALS
                         if signal.getsignal(s) is not signal.SIG_IGN}
            self._old_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
            Interrupts._active = self
        return self

    def __exit__(self, *exc: object) -> None:
        if Interrupts._active is self:
            for s, h in self._old.items():
                signal.signal(s, h)
            sys.unraisablehook = self._old_hook
            Interrupts._active = None
