"""The trigger source: when trigger k is issued, and its publication to the nodes.

Periodic methods issue trigger ``k`` at ``T_k = t0 + (k - k0) / f`` (by
multiplication, so the grid never drifts); a rate change (BiDES adaptation)
rebases the grid at the next trigger, counting periods from there. Lock-Step
and RPC issue no periodic triggers: the aligner calls :meth:`TriggerSource.barrier_done`
when a frame is complete, and trigger ``k+1`` follows at the grid time or at
once if the barrier was late (docs/concepts/methods.md).

The source owns only the clock of triggers; what happens at an issue (the
whole-swarm physics step, the collector, the aligner) is the server's
``on_frame`` callback, and how trigger ``k`` reaches the nodes is its
``publish`` callback (a message per node on the per-message engine, one call
into the compiled core on the cohort engine, one MQTT message in live mode).
It runs on any :class:`~sigma_des.core.clock.Clock`: the DES kernel and the live
loop issue triggers by this one rule.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sigma_des.core.clock import TRIGGER, Clock
from sigma_des.core.filled import filled
from sigma_des.events.align.hlc_clock import HLC, Stamp

__all__ = ["BARRIER_METHODS", "TriggerSource"]

#: Methods whose next trigger waits for the current frame (no periodic triggers).
BARRIER_METHODS = ("lockstep", "rpc")


class TriggerSource:
    """Issues triggers on the periodic grid or after each barrier.

    Args:
        clock: the clock (DES kernel or live loop).
        f_trig: initial trigger rate (Hz).
        history_frames: length of the ring of issue times.
        barrier: True for Lock-Step/RPC (triggers wait for :meth:`barrier_done`).
        on_frame: ``on_frame(k, t, dt)`` runs at the issue of trigger ``k``.
        publish: ``publish(k, stamp)`` sends trigger ``k``; None: the aligner
            sends its own requests (RPC).
        hlc: the server's hybrid logical clock stamping triggers (None: no stamps).
        end: no trigger is issued at or after this time (the run's end; a DES
            run never processes an event there, a live loop runs past it).

    Attributes:
        f_trig: the current rate (takes effect from the next trigger).
        latest: index of the newest trigger issued (-1 before the first).
        trig_time: issue time of frame ``k`` at ``k % history_frames``.
    """

    def __init__(
        self,
        clock: Clock,
        f_trig: float,
        history_frames: int,
        barrier: bool,
        on_frame: Callable[[int, float, float], None],
        publish: Callable[[int, Stamp | None], None] | None,
        hlc: HLC | None,
        end: float = math.inf,
    ) -> None:
        self.clock = clock
        self.end = end
        self.f_trig = f_trig
        self.latest = -1
        self.H = history_frames
        self.trig_time = filled(history_frames, np.nan)
        self.barrier = barrier
        self.on_frame = on_frame
        self.publish = publish
        self.hlc = hlc
        # the grid T_k = t0 + (k - k0) / f
        self.base: tuple[float, int, float] = (0.0, 0, f_trig)

    def start(self) -> None:
        """Schedule the first trigger at t = 0."""
        self.clock.call_at(0.0, self.issue, priority=TRIGGER)

    def next_trigger(self) -> tuple[int, float]:
        """Frame index and step ``dt`` of the next trigger issue."""
        return self.latest + 1, 1.0 / self.f_trig

    def issue(self) -> None:
        """Issue the next trigger: the frame callback, the publication, the next issue."""
        t = self.clock.now
        if t >= self.end:
            return
        k, dt = self.next_trigger()
        self.trig_time[k % self.H] = t
        self.latest = k
        self.on_frame(k, t, dt)
        stamp = self.hlc.send(t) if self.hlc is not None else None
        if self.publish is not None:
            self.publish(k, stamp)
        if not self.barrier:
            if self.f_trig != self.base[2]:  # the rate changed: count periods from here
                self.base = (t, k, self.f_trig)
            t0, k0, f = self.base
            self.clock.call_at(t0 + (k + 1 - k0) / f, self.issue, priority=TRIGGER)

    def barrier_done(self, frame: int) -> None:
        """Schedule trigger ``frame+1``, not sooner than ``1/f_trig`` after ``frame``.

        The earliest time comes from the grid; a barrier that completes later than
        that issues the trigger at once and restarts the grid there.
        """
        k = frame + 1
        t0, k0, f = self.base
        if self.f_trig != f:  # the rate changed: count periods from trigger ``frame``
            t0, k0, f = self.base = (float(self.trig_time[frame % self.H]), frame, self.f_trig)
        t = t0 + (k - k0) / f
        now = self.clock.now
        if t < now:  # the barrier was late: trigger now, count periods from here
            t = now
            self.base = (now, k, f)
        self.clock.call_at(t, self.issue, priority=TRIGGER)

    def set_rate(self, f_trig: float) -> None:
        """Change the rate; it takes effect from the next trigger (the grid rebases there)."""
        self.f_trig = f_trig

    def due(self) -> bool:
        """True if the next call of the clock is a trigger issue."""
        return self.clock.head_is(self.issue)
