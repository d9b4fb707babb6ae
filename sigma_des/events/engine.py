"""The per-message engine: one alignment method over the whole distributed loop.

This is the executable specification (docs/concepts/engines.md). Every message
is an event (SimPy events with callbacks, no process per message):

trigger source ──PUBLISH──▶ broker ──N deliveries──▶ physics nodes ──(compute on
host cores)──▶ state PUBLISH ──▶ broker ──▶ alignment server ──(align ticks)──▶
renderer samples (render ticks); behaviour commands travel back server ─▶ node.

Each concept has its own room, composed here: the alignment server's loop
(trigger source, aligner, alignment and render ticks, collector:
:mod:`sigma_des.events.server`, shared with the live mode), the physics truth
stepped at each issue (:mod:`sigma_des.events.truth`), the physics nodes
(:mod:`sigma_des.events.node`), the network (:mod:`sigma_des.net`). This module
supplies the server's simulated transport, wires the parts, runs the run loop, and
offers the stepping hook (``advance_until`` / ``pending_state``) that
``sigma_des.env`` uses. Messages are carried by the run's message core
(:class:`~sigma_des.events.message_core.MessageCore`: SimPy events on the network,
or the compiled core), which the run loop brings up to each control event.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.gcpause import gc_paused
from sigma_des.core.models import Behaviour, DynamicsModel
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.events.align.base import OneState
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.growth import run_finished
from sigma_des.events.fast.spare import Spare
from sigma_des.events.jobs import step_draws
from sigma_des.events.message_core import EventCore, MessageCore
from sigma_des.events.node import PhysicsNodes
from sigma_des.events.server import AlignmentServer
from sigma_des.events.spec import RunSpec
from sigma_des.events.tap import Tap
from sigma_des.events.truth import NO_LOG, SwarmTruth
from sigma_des.metrics.fidelity import TrajectoryLog
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.dds import make_network
from sigma_des.net.kinds import COMMAND
from sigma_des.net.kinds import TRIGGER as K_TRIGGER
from sigma_des.net.message import Msg
from sigma_des.net.network import Network

__all__ = ["MethodRun", "PAUSED", "TRIGGER_DUE", "END"]

#: Stop codes of :meth:`MethodRun.advance_until` (the stepping hook of ``sigma_des.env``).
PAUSED = 0
TRIGGER_DUE = 1
END = 2


class MethodRun(AlignmentServer):
    """One scenario under one alignment method: the components, wired.

    The server's loop (trigger, ticks, aligner, collector) is
    :class:`~sigma_des.events.server.AlignmentServer`'s, on the simulation kernel;
    this class supplies its simulated transport (the hooks) and the run loop.

    Args:
        spec: the run spec (``Scenario.run_spec()``).
        method: ``none``, ``lockstep``, ``hlc``, ``bides`` or ``rpc``.
        dynamics: the vectorised dynamics model.
        behaviour: behaviour producing commands (None: no commands).
        compiled: process messages in the compiled core
            (:class:`~sigma_des.events.fast.driver.CompiledCore`) instead of as
            SimPy events; raises ``CohortFallback`` if the scenario needs a feature
            the core does not reproduce.
        metrics: collect the run's measurements (False: no collector, no render ticks
            and no fidelity log, see :class:`~sigma_des.events.server.AlignmentServer`;
            :meth:`run` then cannot return results, :meth:`trajectory` has no log).
        spare: what a retired compiled core handed back
            (:meth:`~sigma_des.events.fast.driver.CompiledCore.retire`), for the compiled
            core to refill instead of making new arrays (the same state; unread without
            ``compiled``).

    Attributes:
        trigger: the trigger source.
        truth: the physics truth (true state per frame, checkpoints).
        nodes: the physics nodes (jobs, commands, rollbacks, published states).
        aligner: the alignment server's method.
        collector: the measurement sink.
        net: the broker and links.
        pending_state: the state of the next trigger's frame, computed outside
            (batched physics of ``sigma_des.env``); None: the issue steps the swarm.
        tap: recording tap (:meth:`record`; the base :class:`~sigma_des.events.tap.Tap`
            records nothing).
        core: the message core (:class:`~sigma_des.events.message_core.EventCore`, or
            the compiled core).
    """

    def __init__(
        self,
        spec: RunSpec,
        method: str,
        dynamics: DynamicsModel,
        behaviour: Behaviour | None,
        compiled: bool = False,
        metrics: bool = True,
        spare: Spare | None = None,
    ) -> None:
        n = spec.nodes
        self.kernel = Kernel()
        self.streams = RandomStreams(spec.seed)
        self.net: Network = make_network(self.kernel, spec.net, self.streams, self.deliver)
        self.server = n
        warp = method == "bides" and spec.time_warp
        self.truth = SwarmTruth(dynamics, n, spec.history_frames, spec.log_rate, warp,
                                log=None if metrics else NO_LOG)
        super().__init__(self.kernel, spec, method, dynamics, behaviour, metrics)
        self.nodes = self.make_nodes(warp)
        #: the reusable batch of one each delivered state is handed over in
        self.one = OneState()
        self.wall_seconds = 0.0
        self.pending_state: NDArray[np.float64] | None = None
        #: advance_until returned TRIGGER_DUE and nothing was published since
        self._due_resumed = False
        self.tap = Tap()
        self.core: MessageCore
        if compiled:  # the core reads and writes the command rows in place
            self.nodes.cmd = np.ascontiguousarray(self.nodes.cmd, dtype=np.float64)
            self.core = CompiledCore(self, spare)
        else:
            self.core = EventCore(self.net, self.server, n, spec.trigger_payload_bits,
                                  spec.commands.payload_bits)

    def make_nodes(self, warp: bool) -> PhysicsNodes:
        """The physics nodes of this run (their step-time draws: stream ``compute``)."""
        spec = self.spec
        return PhysicsNodes(
            clock=self.kernel,
            publish=self.net.publish,
            truth=self.truth,
            server=self.server,
            host_of=spec.host_of,
            hosts=spec.hosts,
            cores_per_host=spec.cores_per_host,
            step_time=step_draws(spec.compute, self.streams, spec.host_of),
            faults=spec.faults,
            clocks=NodeClocks(spec.clocks, self.streams.stream("clocks"), self.n),
            hlc=self.method == "hlc",
            warp=spec.theta_warp if warp else None,
            payload_bits=spec.payload_bits,
            cmd=self.dyn.default_command(self.truth.state),
        )

    # ------------------------------------------------------------ state of the parts

    @property
    def state(self) -> NDArray[np.float64]:
        """True state of the swarm at the latest frame."""
        return self.truth.state

    # ------------------------------------------------------------ transport (server hooks)

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: re-request ``node``'s state of ``frame`` (one PUBLISH, one delivery)."""
        self.core.publish_rerequest(node, frame, retry)

    def rpc_call(self, node: int, frame: int) -> None:
        """RPC: send ``node`` the request for ``frame`` (trigger ``frame`` to that node only)."""
        self.net.publish(
            self.server,
            K_TRIGGER,
            self.server,
            frame,
            (frame, None),
            self.spec.trigger_payload_bits,
            (node,),
        )

    # ------------------------------------------------------------ trigger issue

    def on_frame(self, k: int, t: float, dt: float) -> None:
        """Trigger ``k`` is issued at ``t``: step the true swarm, tell collector and aligner."""
        pending = self.pending_state
        self.pending_state = None  # stepped outside with the very same (state, cmd, dt, k)
        self.truth.step_frame(k, dt, self.nodes.cmd, pending)
        super().on_frame(k, t, dt)

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """Publish trigger ``k`` to every node (the message core's trigger fan-out)."""
        self.tap.issue(k, self.kernel.now)
        self.core.publish_trigger(k, stamp)

    # ------------------------------------------------------------ deliveries

    def deliver(self, m: Msg) -> None:
        """The network delivered message ``m`` to ``m.client`` (a node or the server)."""
        t = self.kernel.now
        # the latency ends at the client's receipt (before its CPU burst), or now
        t_recv = t if math.isnan(m.t_recv) else m.t_recv
        self.collector.delivered(m.kind, m.subject, m.index, m.t_pub, t_recv)
        if m.client == self.server:
            frame, gen, obs, stamp = m.payload
            self.aligner.on_states(self.one.fill(t, m.subject, frame, gen, obs, stamp))
            return
        self.nodes.deliver(m.client, m.kind, m.index, m.payload, t)

    def record(self, tap: Tap) -> None:
        """Record this run through ``tap`` (attach before :meth:`run`)."""
        self.tap = tap
        # each delivery by the network, now also recorded (the compiled core hands the
        # tap its own batches: its messages never reach the network)
        self.net.deliver = self.deliver_recorded

    def deliver_recorded(self, m: Msg) -> None:
        """:meth:`deliver`, after handing the delivery (duplicates included) to the tap."""
        t = self.kernel.now
        if m.client == self.server:
            frame, gen, obs, _stamp = m.payload
            self.tap.states(
                np.array([t]), np.array([m.subject]), np.array([frame]), np.array([gen]),
                obs[None, :],
            )
        elif m.kind == K_TRIGGER:
            self.tap.trigger(m.client, int(m.payload[0]), m.t_pub, t)
        elif m.kind == COMMAND:
            self.tap.commands(np.array([m.client]), m.index, m.t_pub, np.array([t]),
                              m.payload[1][None, :])
        self.deliver(m)

    # ------------------------------------------------------------ server hooks

    def tick_cost(self, t: float) -> None:
        """An alignment tick: a ``deployment.server_tick`` burst on the server's process."""
        self.core.server_tick(t)  # the CPU state lives in the message core

    def loop_free(self, t: float) -> float:
        """When the server's loop thread is free of the bursts queued on it by ``t``."""
        return self.core.server_free(t)

    def truth_positions(self, frame: int) -> NDArray[np.float64] | None:
        """True positions of ``frame`` (None once it left the truth ring)."""
        return self.truth.positions(frame)

    def snapshot_taken(self, t: float) -> None:
        """A new snapshot: to the recording tap."""
        al = self.aligner
        self.tap.snapshot(t, al.aligned_frame, al.shown_frame, al.shown_obs)

    def rendered(self, t: float) -> None:
        """A render tick: to the recording tap."""
        self.tap.render(t, self.aligner.shown_gen)

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """Publish ``cmds[i]`` (stamped ``stamp``) to each node ``i`` of ``nodes``, in order."""
        self._due_resumed = False  # new messages: the core must run again before anything
        self.core.publish_commands(tick, stamp, nodes, cmds)

    def trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True positions logged at ``fidelity.log_rate`` Hz of physics time, so far."""
        return self.truth.trajectory()

    def trajectory_log(self) -> TrajectoryLog:
        """The log :meth:`trajectory` reads, for readers that take a block at a time."""
        return self.truth.trajectory_log()

    # ------------------------------------------------------------ run

    def run(self, progress: Callable[[float], None] | None = None) -> dict[str, Any]:
        """Run to ``duration`` and return the collector's results.

        The run is over then: the truth's rings are released
        (:meth:`~sigma_des.events.truth.SwarmTruth.release`; :meth:`trajectory` still
        returns the whole log) and the message core is closed.
        """
        t0 = time.perf_counter()
        self.start()
        # Millions of short-lived event objects make CPython's cyclic GC run thousands
        # of collections (20-50 % of the wall time at 1000 nodes). Processed events hold
        # no reference cycles (SimPy clears their callbacks), so reference counting frees
        # them; the cyclic GC is paused for the run and one young-generation collection
        # follows it (everything made during the run is young; a full collection would
        # also walk every long-lived object: ~0.1 s with numba loaded).
        with gc_paused(collect=0):
            self.advance(progress)
        self.wall_seconds = time.perf_counter() - t0
        self.core.close()  # the messages still in flight: no result reads them
        out = self.finish()
        # the run is over: its rings go now, not when a full collection finds the run
        # (docs/concepts/engines.md, "The event table's memory"); trajectory() stays
        self.truth.release()
        run_finished(self.truth.nodes.size * self.spec.duration)  # the next run collects it
        return out

    def finish(self) -> dict[str, Any]:
        """The collector's results, from the run's, the aligner's and the network's reports."""
        return self.results(rollbacks=self.truth.rollbacks, resim_steps=self.truth.resim_steps,
                            history_misses=self.nodes.history_misses,
                            wall_seconds=self.wall_seconds, events=self.kernel.events,
                            net=self.net, cpu=self.net.cpu_report())

    def load_kernels(self) -> int:
        """Load the compiled kernels this run's message core calls from Python, now.

        For the warm-ups of benchmarks and profiles
        (:meth:`~sigma_des.events.fast.driver.CompiledCore.load_kernels`); the
        per-message engine has none (0).

        Returns:
            The number of kernels that were not loaded yet.
        """
        core = self.core
        return core.load_kernels() if isinstance(core, CompiledCore) else 0

    def next_trigger(self) -> tuple[int, float]:
        """Frame index and step ``dt`` of the next trigger issue (after ``TRIGGER_DUE``)."""
        return self.trigger.next_trigger()

    def trigger_due(self) -> bool:
        """True when the next event is a trigger issue still to be stepped here."""
        return self.pending_state is None and self.trigger.due()

    def advance_until(self, stop: Callable[[], bool]) -> int:
        """Process events one by one until ``stop()`` holds, a trigger is due, or the end.

        The stepping hook of ``sigma_des.env`` (call :meth:`start` first). Returns
        ``PAUSED`` when ``stop()`` became true after an event (e.g. a behaviour that
        only captured the view at a command tick: the caller then publishes commands
        with :meth:`publish_commands` at the same simulated time, exactly as if the
        behaviour had returned them); ``TRIGGER_DUE`` when the next event is a trigger
        issue and :attr:`pending_state` is None: every message at or before its time
        has been processed, so ``self.nodes.cmd`` is final and the caller may step
        ``(self.state, self.nodes.cmd, *self.next_trigger())`` itself (batched with other
        runs), set :attr:`pending_state` and call again; ``END`` when the next event
        is at or after ``duration``. Processing order is that of :meth:`run`.
        """
        k = self.kernel
        core = self.core
        dur = self.spec.duration
        if self._due_resumed:
            self._due_resumed = False
            if stop():
                return PAUSED
            if self.pending_state is not None:
                # resumed after TRIGGER_DUE with the trigger's state: nothing ran and
                # nothing was published since the core reached the trigger's time, so
                # bringing it there again would run nothing; the trigger issues now
                k.step()
        while True:
            if stop():
                return PAUSED
            tc = k.peek()
            last = tc >= dur
            if core.advance_to(dur if last else tc, last):
                continue  # a barrier completed: a trigger may now come before tc
            if last:
                core.write_back()
                return END
            if self.trigger_due():
                self._due_resumed = True
                return TRIGGER_DUE
            k.step()

    def advance(self, progress: Callable[[float], None] | None) -> None:
        """Process every event at a time ``< duration`` (nothing at exactly ``duration``).

        The core's messages run before each control event (messages first at equal
        times). The strict bound is part of the model: which events a run covers must
        not depend on how an engine breaks ties at the end time. ``progress`` is
        called at each whole simulated second and at ``duration``.
        """
        env = self.kernel.env
        peek, step = env.peek, env.step  # the hot loop: bound methods, no wrapper per event
        advance_to = self.core.advance_to
        dur = self.spec.duration
        tell = progress if progress is not None else _silent
        next_p = 1.0 if progress is not None else math.inf
        while True:
            tc = peek()
            last = tc >= dur
            bound = dur if last else tc
            if advance_to(bound, last):
                continue  # a barrier completed: a trigger may now come before tc
            while next_p < dur and next_p <= bound:
                tell(next_p)
                next_p += 1.0
            if last:
                break
            step()
        tell(dur)
        self.core.write_back()


def _silent(t: float) -> None:
    """No progress report."""
