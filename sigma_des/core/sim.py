"""Thin glue over SimPy: schedule plain callbacks without a process per message.

A :class:`Call` is a SimPy event whose only callback runs ``fn(*args)``; it is
pushed straight onto the environment's queue with a priority. Priorities order
simultaneous events deterministically: message arrivals first, then trigger
issue, alignment ticks and render ticks (so "a command that reached the node
before trigger k was issued" includes one arriving at the same instant).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from heapq import heappush
from typing import Any

import simpy

from sigma_des.core.clock import ALIGN, ARRIVAL, RENDER, TRIGGER

__all__ = ["ARRIVAL", "TRIGGER", "ALIGN", "RENDER", "Kernel"]


class Call(simpy.Event):
    """A pre-triggered SimPy event that calls ``fn(*args)`` when processed."""

    __slots__ = ("fn", "args")

    def __init__(self, env: simpy.Environment, fn: Callable[..., Any], args: tuple[Any, ...]):
        self.env = env
        self.callbacks = [self._fire]
        self._ok = True
        self._value = None
        self.fn = fn
        self.args = args

    def _fire(self, _event: simpy.Event) -> None:
        self.fn(*self.args)


class Kernel:
    """A SimPy environment plus callback scheduling and an event counter.

    The DES's :class:`~sigma_des.core.clock.Clock` (``now``, ``call_at``, ``head_is``).
    """

    def __init__(self) -> None:
        self.env = simpy.Environment()
        self.events = 0

    @property
    def now(self) -> float:
        """Current simulated (true) time in seconds."""
        return float(self.env._now)  # type: ignore[attr-defined]  # (Environment.now's)

    def at(self, t: float, fn: Callable[..., Any], *args: Any, priority: int = ARRIVAL) -> None:
        """Run ``fn(*args)`` at absolute time ``t`` (not before now)."""
        env = self.env
        if t < env._now:
            raise ValueError(f"cannot schedule in the past: t={t} < now={env._now}")
        self.events += 1
        # same tuple as Environment.schedule(), pushed directly: this is the hot path
        heappush(env._queue, (t, priority, next(env._eid), Call(env, fn, args)))  # type: ignore[misc]

    #: the :class:`~sigma_des.core.clock.Clock` name of :meth:`at`
    call_at = at

    def count(self, events: int) -> None:
        """Count ``events`` handled outside the queue (by the compiled message core)."""
        self.events += events

    def jump_to(self, t: float) -> None:
        """Set the clock to ``t`` between two events (a backend that ran events itself).

        The compiled message core processes messages outside SimPy; when it stops at
        a message's time, the control code that follows must see that time.
        """
        self.env._now = t  # type: ignore[attr-defined]

    def run(self, until: float) -> None:
        """Process events up to (and including those at) time ``until``."""
        self.env.run(until=until)

    def peek(self) -> float:
        """Time of the next event (``inf`` when none is scheduled): Environment.peek's."""
        q = self.env._queue  # type: ignore[attr-defined]
        return float(q[0][0]) if q else math.inf

    def step(self) -> None:
        """Process the next event."""
        self.env.step()

    def head_is(self, fn: Callable[..., Any]) -> bool:
        """True if the next event is a :class:`Call` of ``fn``."""
        q = self.env._queue  # type: ignore[attr-defined]
        return bool(q) and getattr(q[0][3], "fn", None) == fn
