"""The alignment server's loop: trigger issue, alignment, command and render ticks.

Written once for both engines (docs/concepts/engines.md): the DES
(:class:`~sigma_des.events.engine.MethodRun`) and the live server
(:class:`~sigma_des.live.server.LiveServer`) are subclasses that supply only the
transport, in the spirit of SimPy's ``BaseResource`` (``_do_put``/``_do_get``):

* :meth:`AlignmentServer.publish_trigger`, :meth:`~AlignmentServer.publish_commands`,
  :meth:`~AlignmentServer.rerequest`: how a trigger, a tick's commands and a
  Lock-Step re-request leave the server;
* :meth:`AlignmentServer.on_frame`: what else happens at an issue (the DES steps
  its physics truth there);
* :meth:`AlignmentServer.tick_cost`: the CPU an alignment tick spends (the DES
  charges a burst on the server's process; live spends real CPU);
* :meth:`AlignmentServer.truth_positions`, :meth:`~AlignmentServer.snapshot_taken`,
  :meth:`~AlignmentServer.rendered`: the truth a render tick compares with (the
  live server has none) and what is recorded.

Everything else is here: the trigger source (:mod:`sigma_des.events.trigger`),
the aligner and its :class:`~sigma_des.events.align.base.ServerContext`, the
alignment ticks at ``(j + align_phase) / f_align`` (align, measure, send commands
every ``commands.every`` ticks), the render ticks at ``(j + render_phase) /
f_render`` (sample AoI against the truth), and the collector. Times come from a
:class:`~sigma_des.core.clock.Clock`; nothing runs at or after ``duration``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.clock import ALIGN, RENDER, TRIGGER, Clock
from sigma_des.core.models import Behaviour, DynamicsModel, SwarmView
from sigma_des.events.align import make_aligner
from sigma_des.events.align.base import Aligner
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.events.spec import RunSpec
from sigma_des.events.trigger import BARRIER_METHODS, TriggerSource
from sigma_des.metrics.collector import Collector
from sigma_des.metrics.null import NullCollector
from sigma_des.metrics.reports import NetCounters, NetReport, RunReport
from sigma_des.net.cpu import CpuReport

__all__ = ["AlignmentServer"]


class AlignmentServer:
    """The server side of one run under one method, on a clock; transport in hooks.

    Args:
        clock: the clock (DES kernel or live loop).
        spec: the run spec (tick rates and phases, trigger rate, aligner, collector).
        method: ``none``, ``lockstep``, ``hlc``, ``bides`` or ``rpc``.
        dynamics: the dynamics model (the behaviour's commands are its).
        behaviour: behaviour producing commands (None: no commands).
        metrics: collect the run's measurements; False: a
            :class:`~sigma_des.metrics.null.NullCollector` and no render ticks
            (they only sample for the metrics), for runs nobody measures (a learning
            env's scenes): every other event happens as with metrics.

    Attributes:
        trigger: the trigger source.
        aligner: the method's aligner (this object is its ``ServerContext``).
        collector: the measurement sink.
        align_tick: index of the next alignment tick.
        render_tick: index of the next render tick.
    """

    def __init__(
        self,
        clock: Clock,
        spec: RunSpec,
        method: str,
        dynamics: DynamicsModel,
        behaviour: Behaviour | None,
        metrics: bool = True,
    ) -> None:
        self.clock = clock
        self.spec = spec
        self.method = method
        self.n = spec.nodes
        self.dyn = dynamics
        self.behaviour = behaviour if spec.commands.enabled else None
        self.trigger = TriggerSource(
            clock,
            spec.f_trig,
            spec.history_frames,
            method in BARRIER_METHODS,
            self.on_frame,
            None if method == "rpc" else self.publish_trigger,  # RPC: the aligner's requests
            HLC() if method == "hlc" else None,
            spec.duration,
        )
        self.aligner: Aligner = make_aligner(method, spec.nodes, self, spec.align)
        self.metrics = metrics
        self.collector = (Collector if metrics else NullCollector)(spec.collect, method)
        self.align_tick = 0
        self.render_tick = 0

    # ------------------------------------------------------------ transport hooks

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """Send trigger ``k`` (stamped by the server's HLC, or None) to every node."""
        raise NotImplementedError

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """Send ``cmds[i]`` (stamped ``stamp``) to each node ``i`` of ``nodes``, in order."""
        raise NotImplementedError

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: ask ``node`` again for its state of ``frame``."""
        raise NotImplementedError

    def tick_cost(self, t: float) -> None:
        """The alignment tick at ``t`` spends the server's CPU (nothing by default)."""

    def truth_positions(self, frame: int) -> NDArray[np.float64] | None:
        """True ``(n, 3)`` positions of ``frame`` for the render tick (None: unknown)."""
        return None

    def snapshot_taken(self, t: float) -> None:
        """The aligner made a new snapshot at ``t`` (recording hook)."""

    def rendered(self, t: float) -> None:
        """A render tick sampled the snapshot at ``t`` (recording hook)."""

    # ------------------------------------------------------------ ServerContext

    def now(self) -> float:
        """Current time (s)."""
        return self.clock.now

    def call_at(self, t: float, fn: Callable[..., Any], *args: Any) -> None:
        """Schedule ``fn(*args)`` at ``t`` (the aligner's timers)."""
        self.clock.call_at(t, fn, *args, priority=TRIGGER)

    @property
    def latest_trigger(self) -> int:
        """Index of the newest trigger issued (-1 before the first)."""
        return self.trigger.latest

    @property
    def f_trig(self) -> float:
        """The current trigger rate (Hz)."""
        return self.trigger.f_trig

    def set_rate(self, f_trig: float) -> None:
        """Change the trigger rate; takes effect from the next trigger."""
        self.trigger.set_rate(f_trig)
        self.collector.rate_change(self.clock.now, f_trig)

    def barrier_done(self, frame: int) -> None:
        """Lock-Step/RPC: schedule trigger ``frame+1`` (see :meth:`TriggerSource.barrier_done`)."""
        self.trigger.barrier_done(frame)

    # ------------------------------------------------------------ trigger issue

    def on_frame(self, k: int, t: float, dt: float) -> None:
        """Trigger ``k`` is issued at ``t`` with step ``dt``: tell collector and aligner."""
        self.collector.trigger(t, k, dt)
        self.aligner.on_trigger(k, t)

    # ------------------------------------------------------------ ticks

    def loop_free(self, t: float) -> float:
        """When the server's loop thread has served what was queued on it by ``t`` (``t``
        if nothing was): a tick due at ``t`` runs then. Live, the loop drains its inbox
        before it looks at its timers, so a state read before the tick was due is
        aligned by it; the DES answers from its CPU stage (:meth:`MessageCore.server_free`).
        This default (live's) waits for nothing: the live loop waits by itself."""
        return t

    def align(self) -> None:
        """Alignment tick: once the loop thread is free (:meth:`loop_free`), align,
        measure, record, send commands and schedule the next tick."""
        self._once_free(self._align, ALIGN)

    def _once_free(self, tick: Callable[[], None], priority: int) -> None:
        """Run ``tick`` now, or when the loop thread is free (:meth:`loop_free`)."""
        t = self.clock.now
        free = self.loop_free(t)
        if free > t:
            self.clock.call_at(free, tick, priority=priority)
        else:
            tick()

    def _align(self) -> None:
        t = self.clock.now
        if t >= self.spec.duration:
            return
        self.tick_cost(t)  # before the tick's commands: they queue behind it
        al = self.aligner
        al.align(t)
        self.collector.shown(t, al.shown_gen)
        if al.new_snapshot:
            self.collector.snapshot(t)
            self.snapshot_taken(t)
        if self.behaviour is not None and self.align_tick % self.spec.commands.every == 0:
            self.send_commands()
        self.align_tick += 1
        # a tick run late (behind the loop's queue) may pass the next one's time: now, then
        nxt = self.align_time(self.align_tick)
        self.clock.call_at(nxt if nxt > t else t, self.align, priority=ALIGN)

    def send_commands(self) -> None:
        """Ask the behaviour for commands on the shown snapshot and publish them."""
        al = self.aligner
        valid = ~np.isnan(al.shown_gen)
        if not valid.any():
            return
        assert self.behaviour is not None
        view = SwarmView(
            obs=al.shown_obs, frame=al.shown_frame, valid=valid, aligned_frame=al.aligned_frame
        )
        cmds = self.behaviour.commands(view, self.dyn)
        ok = ~np.isnan(cmds).all(axis=1)  # NaN cells mean 'keep'; an all-NaN row, 'none'
        self.publish_commands(self.align_tick, al.aligned_frame, np.flatnonzero(ok), cmds)

    def render(self) -> None:
        """Render tick: once the loop thread is free (:meth:`loop_free`), sample what is
        shown against the truth and schedule the next tick."""
        self._once_free(self._render, RENDER)

    def _render(self) -> None:
        t = self.clock.now
        if t >= self.spec.duration:
            return
        al = self.aligner
        ref = al.aligned_frame
        self.collector.render(
            t,
            al.shown_gen,
            al.shown_frame,
            al.shown_obs,
            al.flag,
            self.truth_positions(ref),
            self.trigger.f_trig,
            self.trigger.latest,
            ref,
        )
        self.rendered(t)
        self.render_tick += 1
        nxt = self.render_time(self.render_tick)
        self.clock.call_at(nxt if nxt > t else t, self.render, priority=RENDER)

    def align_time(self, j: int) -> float:
        """Alignment tick ``j`` at ``(j + align_phase) / f_align`` (multiplied, no drift)."""
        return (j + self.spec.align_phase) / self.spec.f_align

    def render_time(self, j: int) -> float:
        """Render tick ``j`` at ``(j + render_phase) / f_render``."""
        return (j + self.spec.render_phase) / self.spec.f_render

    def start(self) -> None:
        """Schedule the first trigger (t = 0), alignment tick and render tick (their phases;
        no render ticks without metrics)."""
        self.trigger.start()
        self.clock.call_at(self.align_time(0), self.align, priority=ALIGN)
        if self.metrics:
            self.clock.call_at(self.render_time(0), self.render, priority=RENDER)

    def results(self, *, rollbacks: int, resim_steps: int, history_misses: int,
                wall_seconds: float, events: int, net: NetCounters,
                cpu: CpuReport | None = None) -> dict[str, Any]:
        """The collector's results of the finished run: the run's own report (with the
        trigger rate in force), the aligner's and the network's.

        Args:
            rollbacks: time-warp rollbacks of the nodes.
            resim_steps: physics steps they re-simulated.
            history_misses: states published of a frame no longer held.
            wall_seconds: wall-clock time of the run (s).
            events: events the clock handled.
            net: the network's counters (simulated, or measured live).
            cpu: the CPU stage's counters (None: none).
        """
        run = RunReport(f_trig=self.f_trig, rollbacks=rollbacks, resim_steps=resim_steps,
                        history_misses=history_misses, wall_seconds=wall_seconds,
                        events=events)
        return self.collector.finish(run, self.aligner.report(), NetReport.of(net), cpu)
