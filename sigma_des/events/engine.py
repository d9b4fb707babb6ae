"""The per-message engine: one alignment method over the whole distributed loop.

This is the executable specification (DESIGN §6). Every message is an event
(SimPy events with callbacks, no process per message):

trigger source ──PUBLISH──▶ broker ──N deliveries──▶ physics nodes ──(compute on
host cores)──▶ state PUBLISH ──▶ broker ──▶ alignment server ──(align ticks)──▶
renderer samples (render ticks); behaviour commands travel back server ─▶ node.

Physics follows DESIGN §3's frame-boundary rule: a node applies at frame k the
newest command that reached it before trigger k was issued, so the true state
of every node at frame k is known when trigger k is issued and the whole swarm
is stepped then, in one vectorised call. *When* a node computes and publishes
frame k is what the events model. BiDES time warp rolls a node back and
re-simulates its rows from a checkpoint.
"""

from __future__ import annotations

import gc
import heapq
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.base import Behaviour, DynamicsModel, SwarmView
from sigma_des.config import Scenario
from sigma_des.core.draws import DrawCache
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import ALIGN, RENDER, TRIGGER, Kernel
from sigma_des.events.align import make_aligner
from sigma_des.events.align.base import OBS_WIDTH, Aligner, one_state
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.metrics.collector import Collector
from sigma_des.metrics.fidelity import TrajectoryLog
from sigma_des.metrics.reports import NetReport, RunReport
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.dds import make_network
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE
from sigma_des.net.kinds import TRIGGER as K_TRIGGER
from sigma_des.net.network import Network

__all__ = ["MethodRun", "PAUSED", "TRIGGER_DUE", "END"]

_STEP = 0
_ROLLBACK = 1
#: Methods whose next trigger waits for the current frame (no periodic triggers).
BARRIER_METHODS = ("lockstep", "rpc")

#: Stop codes of :meth:`MethodRun.advance_until` (the stepping hook of ``sigma_des.env``).
PAUSED = 0
TRIGGER_DUE = 1
END = 2


class MethodRun:
    """One scenario under one alignment method.

    Args:
        sc: the scenario.
        method: ``none``, ``lockstep``, ``hlc``, ``bides`` or ``rpc``.
        dynamics: the vectorised dynamics model.
        behaviour: behaviour producing commands (None: no commands).
    """

    def __init__(
        self, sc: Scenario, method: str, dynamics: DynamicsModel, behaviour: Behaviour | None
    ) -> None:
        self.sc = sc
        self.method = method
        n = self.n = sc.nodes
        self.kernel = Kernel()
        self.streams = RandomStreams(sc.seed)
        self.net: Network = make_network(self.kernel, sc.net_setup(), self.streams, self._deliver)
        self.server = n
        self.all_nodes = list(range(n))
        self._nodes = np.arange(n, dtype=np.int64)
        self.dyn = dynamics
        self.behaviour = behaviour if sc.commands.enabled else None
        # trigger source
        self.f_trig = sc.f_trig
        self.latest_trigger = -1
        H = self.H = sc.history_frames
        self.trig_time = np.full(H, np.nan)
        self.frame_dt = np.zeros(H)
        # physics truth: checkpoints and published states per frame (ring of H)
        self.initial = dynamics.initial_state(n)
        self.state = self.initial.copy()
        # checkpoints are only read by time-warp rollbacks: other runs keep none
        warp = method == "bides" and sc.bides.time_warp
        self.ckpt = np.zeros(((H if warp else 0),) + self.state.shape)
        self.obs_hist = np.full((H, n, OBS_WIDTH), np.nan)
        self.slot_frame = np.full(H, -1, dtype=np.int64)
        # physics time of each frame (sum of its dt), and the fidelity log, which takes
        # a frame only when it leaves the ring (it can no longer be rolled back)
        self.phys_t = 0.0
        self.phys_hist = np.zeros(H)
        self.traj = TrajectoryLog(sc.fidelity.log_rate, dynamics.observe(self.initial)[:, 9:12])
        self.cmd = dynamics.default_command(self.state)
        self.cmd_stamp = [-1] * n
        # nodes
        host_of = sc.host_of
        self.host_of = host_of
        self.cores: list[list[float]] = [[0.0] * sc.cores_per_host for _ in range(sc.hosts)]
        self.node_frame = [-1] * n
        self.node_req = [-1] * n
        self.node_target = [-1] * n
        self.node_busy = [False] * n
        self.rb_steps = [0] * n
        self.last_pub: list[tuple[int, float, NDArray[np.float64], Stamp | None] | None] = [
            None
        ] * n
        st = self.streams.stream("compute")
        step = sc.compute.step_time
        self.step_time = DrawCache(
            n,
            lambda s, k, i, a: step.sample(st, k, s, i, a),
            constant=step.value if step.dist == "constant" else None,
        )
        self.crash_at = [math.inf] * n
        self.slow: dict[int, list[tuple[float, float, float]]] = {}
        for f in sc.faults:
            if f.kind == "crash":
                self.crash_at[f.node] = min(self.crash_at[f.node], f.start)
            elif f.kind == "slow":
                self.slow.setdefault(f.node, []).append((f.start, f.end, f.factor))
        self.rollbacks = 0
        self.resim_steps = 0
        self.history_misses = 0
        # HLC
        self.use_hlc = method == "hlc"
        self.clocks = NodeClocks(sc.clocks, self.streams.stream("clocks"), n)
        self._offset = self.clocks.offset.tolist()
        self._drift = (self.clocks.drift_ppm * 1e-6).tolist()
        self.hlc = [HLC() for _ in range(n)] if self.use_hlc else []
        self.server_hlc = HLC()
        # server
        self.aligner: Aligner = make_aligner(method, n, self, sc.align_params())
        self.collector = Collector(sc.collector_spec(), method)
        self.align_tick = 0
        self.render_tick = 0
        # periodic triggers: T_k = t0 + (k - k0) / f, rebased when the rate changes
        self._base: tuple[float, int, float] = (0.0, 0, sc.f_trig)
        self.wall_seconds = 0.0
        #: the state of the next trigger's frame, computed outside (batched physics of
        #: ``sigma_des.env``); None: :meth:`_issue` steps the swarm itself
        self.pending_state: NDArray[np.float64] | None = None
        #: recording tap (``sigma_des.record.tap.RecordTap``), set before ``run``; None: off
        self.tap: Any = None

    # ------------------------------------------------------------ ServerContext

    def now(self) -> float:
        """Current simulated time (s)."""
        return self.kernel.now

    def call_at(self, t: float, fn: Callable[..., Any], *args: Any) -> None:
        """Schedule ``fn(*args)`` at ``t`` (server-side timers)."""
        self.kernel.at(t, fn, *args, priority=TRIGGER)

    def set_rate(self, f_trig: float) -> None:
        """Change the trigger rate; takes effect from the next trigger."""
        self.f_trig = f_trig
        self.collector.rate_change(self.kernel.now, f_trig)

    def barrier_done(self, frame: int) -> None:
        """Lock-Step: schedule trigger ``frame+1`` (not sooner than 1/f_trig after ``frame``).

        The earliest time comes from the trigger grid ``t0 + (k - k0) / f`` (by
        multiplication, so it never drifts); a barrier that completes later than that
        issues the trigger at once and restarts the grid there.
        """
        k = frame + 1
        t0, k0, f = self._base
        if self.f_trig != f:  # the rate changed: count periods from trigger ``frame``
            t0, k0, f = self._base = (float(self.trig_time[frame % self.H]), frame, self.f_trig)
        t = t0 + (k - k0) / f
        now = self.kernel.now
        if t < now:  # the barrier was late: trigger now, count periods from here
            t = now
            self._base = (now, k, f)
        self.kernel.at(t, self._issue, priority=TRIGGER)

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: re-request ``node``'s state of ``frame`` (one PUBLISH, one delivery)."""
        self.net.publish(
            self.server,
            REREQUEST,
            node,
            frame * 64 + min(retry, 63),
            frame,
            self.sc.trigger_payload_bits,
            (node,),
        )

    def rpc_call(self, node: int, frame: int) -> None:
        """RPC: send ``node`` the request for ``frame`` (trigger ``frame`` to that node only)."""
        self.net.publish(
            self.server,
            K_TRIGGER,
            self.server,
            frame,
            (frame, None),
            self.sc.trigger_payload_bits,
            (node,),
        )

    # ------------------------------------------------------------ trigger source

    def _local(self, node: int, t: float) -> float:
        if self.sc.clocks.ntp_period > 0:
            return float(self.clocks.local_time(node, t))
        return t + self._offset[node] + self._drift[node] * t

    def _issue(self) -> None:
        """Issue the next trigger: step the true swarm, publish to every node."""
        t = self.kernel.now
        k = self.latest_trigger + 1
        dt = 1.0 / self.f_trig
        slot = k % self.H
        if self.slot_frame[slot] >= 0:
            self.traj.add(float(self.phys_hist[slot]), self.obs_hist[slot, :, 9:12])
        self.trig_time[slot] = t
        self.frame_dt[slot] = dt
        self.phys_t += dt
        self.phys_hist[slot] = self.phys_t
        pending = self.pending_state
        if pending is None:
            self.state = self.dyn.step(self.state, self.cmd, dt, k, self._nodes)
        else:  # stepped outside with the very same (state, cmd, dt, k): see advance_until
            self.pending_state = None
            self.state = pending
        if self.ckpt.shape[0]:
            self.ckpt[slot] = self.state
        self.obs_hist[slot] = self.dyn.observe(self.state)
        self.slot_frame[slot] = k
        self.latest_trigger = k
        self.collector.trigger(t, k, dt)
        self.aligner.on_trigger(k, t)
        stamp = self.server_hlc.send(t) if self.use_hlc else None
        if self.method != "rpc":  # RPC: the aligner sends each vehicle its request
            self._send_trigger(k, stamp)
        if self.method not in BARRIER_METHODS:
            if self.f_trig != self._base[2]:  # the rate changed: count periods from here
                self._base = (t, k, self.f_trig)
            t0, k0, f = self._base
            self.kernel.at(t0 + (k + 1 - k0) / f, self._issue, priority=TRIGGER)

    def _send_trigger(self, k: int, stamp: Stamp | None) -> None:
        """Publish trigger ``k`` to every node (a hook the cohort engine overrides)."""
        self.net.publish(
            self.server,
            K_TRIGGER,
            self.server,
            k,
            (k, stamp),
            self.sc.trigger_payload_bits,
            self.all_nodes,
        )

    # ------------------------------------------------------------ physics nodes

    def _deliver(
        self, client: int, kind: int, subject: int, index: int, payload: Any, t_pub: float
    ) -> None:
        t = self.kernel.now
        self.collector.delivered(kind, subject, index, t_pub, t)
        if self.tap is not None:
            self._tap_delivery(client, kind, subject, index, payload, t_pub, t)
        if client == self.server:
            frame, gen, obs, stamp = payload
            self.aligner.on_states(one_state(t, subject, frame, gen, obs, stamp))
            return
        if t >= self.crash_at[client]:
            return
        if kind == K_TRIGGER:
            k, stamp = payload
            if self.use_hlc:
                self.hlc[client].receive(self._local(client, t), stamp)
            self._on_trigger(client, k)
        elif kind == COMMAND:
            self._on_command(client, *payload)
        elif kind == REREQUEST:
            self._on_rerequest(client, payload, index)

    def _tap_delivery(
        self,
        client: int,
        kind: int,
        subject: int,
        index: int,
        payload: Any,
        t_pub: float,
        t: float,
    ) -> None:
        """Hand one delivery (duplicates included) to the recording tap."""
        if client == self.server:
            frame, gen, obs, _stamp = payload
            self.tap.states(
                np.array([t]), np.array([subject]), np.array([frame]), np.array([gen]),
                obs[None, :],
            )
        elif kind == K_TRIGGER:
            self.tap.trigger(client, int(payload[0]), t_pub, t)
        elif kind == COMMAND:
            self.tap.commands(np.array([client]), index, t_pub, np.array([t]), payload[1][None, :])

    def _on_trigger(self, i: int, k: int) -> None:
        if k <= self.node_req[i]:
            return  # duplicate or stale trigger
        self.node_req[i] = k
        if not self.node_busy[i]:
            self._start_job(i)

    def _on_rerequest(self, i: int, frame: int, index: int) -> None:
        last = self.last_pub[i]
        if self.node_frame[i] >= frame and last is not None and last[0] == frame:
            self.net.publish(i, REPUBLISH, i, index, last, self.sc.payload_bits, (self.server,))
        elif self.node_req[i] < frame:
            self._on_trigger(i, frame)

    def _start_job(self, i: int) -> None:
        now = self.kernel.now
        target = self.node_req[i]
        cost = 0.0
        for f in range(self.node_frame[i] + 1, target + 1):
            cost += self.step_time.get(_STEP, i, f, 0)
        rb = self.rb_steps[i]
        if rb:
            for j in range(rb):
                cost += self.step_time.get(_ROLLBACK, i, target, j)
            self.rb_steps[i] = 0
        for a, b, factor in self.slow.get(i, ()):
            if a <= now < b:
                cost *= factor
        cores = self.cores[self.host_of[i]]
        free = heapq.heappop(cores)
        start = now if now > free else free
        heapq.heappush(cores, start + cost)
        self.node_busy[i] = True
        self.node_target[i] = target
        self.kernel.at(start + cost, self._complete, i, target)

    def _complete(self, i: int, target: int) -> None:
        t = self.kernel.now
        self.node_busy[i] = False
        if t >= self.crash_at[i]:
            return
        if target > self.node_frame[i]:
            self.node_frame[i] = target
            slot = target % self.H
            if self.slot_frame[slot] != target:
                self.history_misses += 1
            obs = self.obs_hist[slot, i].copy()
            stamp = self.hlc[i].send(self._local(i, t)) if self.use_hlc else None
            payload = (target, t, obs, stamp)
            self.last_pub[i] = payload
            self.net.publish(i, STATE, i, target, payload, self.sc.payload_bits, (self.server,))
        if self.node_req[i] > self.node_frame[i] or self.rb_steps[i]:
            self._start_job(i)

    def _on_command(self, i: int, stamp_frame: int, row: NDArray[np.float64]) -> None:
        if stamp_frame < self.cmd_stamp[i]:
            return  # an older command overtaken by a newer one
        self.cmd_stamp[i] = stamp_frame
        self.cmd[i] = row
        b = self.sc.bides
        if self.method != "bides" or not b.time_warp or stamp_frame < 0:
            return
        current = self.node_target[i] if self.node_busy[i] else self.node_frame[i]
        if current - stamp_frame <= b.theta_warp:
            return
        self._rollback(i, stamp_frame, current, row)

    def _rollback(self, i: int, c: int, current: int, row: NDArray[np.float64]) -> None:
        """Re-simulate node ``i`` from frame ``c`` with command ``row`` (time warp)."""
        oldest = max(0, self.latest_trigger - self.H + 2)
        c = max(c, oldest)
        prev = self.initial[i] if c == 0 else self.ckpt[(c - 1) % self.H, i]
        s = prev[None, :].copy()
        cmd = row[None, :]
        node = np.array([i])
        step_frames = getattr(self.dyn, "step_frames", None)
        if step_frames is not None and c <= self.latest_trigger:
            # the same row steps, compiled in one call (identical to the loop below)
            slots = np.arange(c, self.latest_trigger + 1) % self.H
            states = step_frames(prev, row, self.frame_dt[slots], c, i)
            self.ckpt[slots, i] = states
            s = states[-1:]
        else:
            for f in range(c, self.latest_trigger + 1):
                slot = f % self.H
                s = self.dyn.step(s, cmd, float(self.frame_dt[slot]), f, node)
                self.ckpt[slot, i] = s[0]
        if c <= self.latest_trigger:
            # one observe call for all re-simulated frames (rows are independent)
            slots = np.arange(c, self.latest_trigger + 1) % self.H
            self.obs_hist[slots, i] = self.dyn.observe(self.ckpt[slots, i])
        self.state[i] = s[0]
        steps = max(0, current - c + 1)
        self.rollbacks += 1
        self.resim_steps += steps
        self.rb_steps[i] += steps
        if not self.node_busy[i]:
            self._start_job(i)

    # ------------------------------------------------------------ server ticks

    def _align(self) -> None:
        t = self.kernel.now
        al = self.aligner
        al.align(t)
        self.collector.shown(t, al.shown_gen)
        if al.new_snapshot:
            self.collector.snapshot(t)
            if self.tap is not None:
                self.tap.snapshot(t, al.aligned_frame, al.shown_frame, al.shown_obs)
        if self.behaviour is not None and self.align_tick % self.sc.commands.every == 0:
            self._send_commands(t)
        self.align_tick += 1
        self.kernel.at(self._align_time(self.align_tick), self._align, priority=ALIGN)

    def _send_commands(self, t: float) -> None:
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
        self._send_command_batch(self.align_tick, al.aligned_frame, np.flatnonzero(ok), cmds)

    def _send_command_batch(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """Publish ``cmds[i]`` (stamped ``stamp``) to each node ``i`` of ``nodes``, in order."""
        bits = self.sc.commands.payload_bits
        for i in nodes.tolist():
            self.net.publish(self.server, COMMAND, i, tick, (stamp, cmds[i].copy()), bits, (i,))

    def _render(self) -> None:
        t = self.kernel.now
        al = self.aligner
        ref = al.aligned_frame
        truth = None
        if ref >= 0 and self.slot_frame[ref % self.H] == ref:
            truth = self.obs_hist[ref % self.H, :, 9:12]
        self.collector.render(
            t,
            al.shown_gen,
            al.shown_frame,
            al.shown_obs,
            al.flag,
            truth,
            self.f_trig,
            self.latest_trigger,
            ref,
        )
        if self.tap is not None:
            self.tap.render(t, al.shown_gen)
        self.render_tick += 1
        self.kernel.at(self._render_time(self.render_tick), self._render, priority=RENDER)

    def _align_time(self, j: int) -> float:
        """Alignment tick ``j`` at ``(j + align_phase) / f_align`` (multiplied, no drift)."""
        return (j + self.sc.align_phase) / self.sc.f_align

    def _render_time(self, j: int) -> float:
        """Render tick ``j`` at ``(j + render_phase) / f_render``."""
        return (j + self.sc.render_phase) / self.sc.f_render

    def trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True positions logged at ``fidelity.log_rate`` Hz of physics time, so far."""
        log = self.traj
        first = max(0, self.latest_trigger - self.H + 1)
        for f in range(first, self.latest_trigger + 1):
            slot = f % self.H
            log.add(float(self.phys_hist[slot]), self.obs_hist[slot, :, 9:12])
        return log.arrays()

    # ------------------------------------------------------------ run

    def start(self) -> None:
        """Schedule the first trigger (t = 0), alignment tick and render tick (their phases)."""
        k = self.kernel
        k.at(0.0, self._issue, priority=TRIGGER)
        k.at(self._align_time(0), self._align, priority=ALIGN)
        k.at(self._render_time(0), self._render, priority=RENDER)

    def run(self, progress: Callable[[float], None] | None = None) -> dict[str, Any]:
        """Run to ``duration`` and return the collector's results."""
        t0 = time.perf_counter()
        self.start()
        # Millions of short-lived event objects make CPython's cyclic GC run thousands
        # of collections (20-50 % of the wall time at 1000 nodes). Processed events hold
        # no reference cycles (SimPy clears their callbacks), so reference counting frees
        # them; the cyclic GC is paused for the run and one young-generation collection
        # follows it (everything made during the run is young; a full collection would
        # also walk every long-lived object: ~0.1 s with numba loaded).
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            self._advance(progress)
        finally:
            if was_enabled:
                gc.enable()
            gc.collect(0)
        self.wall_seconds = time.perf_counter() - t0
        return self.finish()

    def finish(self) -> dict[str, Any]:
        """The collector's results, from the run's, the aligner's and the network's reports."""
        run = RunReport(
            f_trig=self.f_trig,
            rollbacks=self.rollbacks,
            resim_steps=self.resim_steps,
            history_misses=self.history_misses,
            wall_seconds=self.wall_seconds,
            events=self.kernel.events,
        )
        return self.collector.finish(run, self.aligner.report(), NetReport.of(self.net))

    def next_trigger(self) -> tuple[int, float]:
        """Frame index and step ``dt`` of the next trigger issue (after ``TRIGGER_DUE``)."""
        return self.latest_trigger + 1, 1.0 / self.f_trig

    def _head_is_issue(self) -> bool:
        q = self.kernel.env._queue  # type: ignore[attr-defined]
        return bool(q) and getattr(q[0][3], "fn", None) == self._issue

    def advance_until(self, stop: Callable[[], bool]) -> int:
        """Process events one by one until ``stop()`` holds, a trigger is due, or the end.

        The stepping hook of ``sigma_des.env`` (call :meth:`start` first). Returns
        ``PAUSED`` when ``stop()`` became true after an event (e.g. a behaviour that
        only captured the view at a command tick: the caller then publishes commands
        with :meth:`_send_command_batch` at the same simulated time, exactly as if the
        behaviour had returned them); ``TRIGGER_DUE`` when the next event is a trigger
        issue and :attr:`pending_state` is None: every message at or before its time
        has been processed, so ``self.cmd`` is final and the caller may step
        ``(self.state, self.cmd, *self.next_trigger())`` itself (batched with other
        runs), set :attr:`pending_state` and call again; ``END`` when the next event
        is at or after ``duration``. Processing order is that of :meth:`run`.
        """
        env = self.kernel.env
        dur = self.sc.duration
        while True:
            if stop():
                return PAUSED
            if env.peek() >= dur:
                return END
            if self.pending_state is None and self._head_is_issue():
                return TRIGGER_DUE
            env.step()

    def _advance(self, progress: Callable[[float], None] | None) -> None:
        """Process every event at a time ``< duration`` (nothing at exactly ``duration``).

        The strict bound is part of the model: which events a run covers must not
        depend on how an engine breaks ties at the end time.
        """
        k = self.kernel
        env = k.env
        dur = self.sc.duration
        t = 0.0
        while t < dur:
            t = min(dur, t + 1.0)
            if t < dur:
                # events at exactly t left behind by run(until) are still processed
                # first by the next call (same heap order), so the split is invisible
                k.run(until=t)
            else:
                while env.peek() < dur:
                    env.step()
            if progress is not None:
                progress(t)
