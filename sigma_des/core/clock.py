"""The clock seam: what the rules (trigger, server ticks, node jobs) need of time.

The trigger source, the alignment server and the physics nodes are written once
against :class:`Clock` and run on two clocks: the DES kernel
(:class:`sigma_des.core.sim.Kernel`, simulated time) and the live loop
(:class:`sigma_des.live.loop.Loop`, the monotonic wall clock; or
:class:`sigma_des.live.loop.VirtualLoop`, virtual time with the live loop's
dispatch). ``now`` is a read-only property, as SimPy's ``Environment.now``.

Simultaneous calls run by priority, then in the order they were scheduled:
message arrivals first, then trigger issue, alignment ticks and render ticks (so
"a command that reached the node before trigger k was issued" includes one
arriving at the same instant). Both clocks keep this order.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

__all__ = ["ALIGN", "ARRIVAL", "RENDER", "TRIGGER", "Clock"]

#: Priorities of simultaneous calls (lower first).
ARRIVAL = 0
TRIGGER = 1
ALIGN = 2
RENDER = 3


class Clock(Protocol):
    """Time and timers, as the rules see them (nothing engine-specific)."""

    @property
    def now(self) -> float:
        """Current time (s since the run's start)."""
        ...

    def call_at(self, t: float, fn: Callable[..., Any], *args: Any,
                priority: int = ARRIVAL) -> None:
        """Run ``fn(*args)`` at time ``t`` (not before ``now``), after every call
        scheduled at ``t`` with a lower ``priority`` or earlier with the same one."""
        ...

    def head_is(self, fn: Callable[..., Any]) -> bool:
        """True if the next call due is one of ``fn``."""
        ...
