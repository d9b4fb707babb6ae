"""The physics nodes: jobs on host cores, commands, time-warp rollbacks, published states.

Each node (docs/concepts/model.md, "Physics nodes") computes one job at a time: on
trigger k it steps from its last computed frame to k, each step costing a
``step_time`` draw keyed by node and frame (plus the re-simulation steps a
rollback owes), times a ``slow`` fault factor, served first come first served by
its host's cores. When the job completes it publishes the frame's row of the
physics truth (:class:`~sigma_des.events.truth.SwarmTruth`) to the server. A
trigger that arrives while the node is busy is remembered and the next job
catches up to it (triggers coalesce). A ``crash`` fault silences the node for
good. Commands replace the node's command row (an older-stamped one is
ignored); under BiDES time warp a command stamped too far behind rolls the node
back. The cost of a job is :func:`~sigma_des.events.jobs.job_cost` (shared with
the compiled core). Lock-Step re-requests are answered by republishing the last state.

These rules are written once (:class:`NodeRules`, on a
:class:`~sigma_des.core.clock.Clock`) and run by two transports, in the spirit of
SimPy's ``BaseResource`` hooks: :class:`PhysicsNodes` publishes through the DES
network, the live host (:class:`sigma_des.live.host.HostNodes`) over MQTT. A rule
object serves any subset of the run's nodes (a live host serves its own): its
node ``i`` is the run's node ``ids[i]``, which keys the draws, clocks and faults.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.clock import Clock
from sigma_des.core.draws import DrawCache
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.events.jobs import job_cost
from sigma_des.events.spec import FaultSpec
from sigma_des.events.truth import SwarmTruth
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER

__all__ = ["NodeRules", "PhysicsNodes", "Published", "crash_times", "slow_windows"]

#: A ``slow`` fault window: (start, end, factor).
SlowWindow = tuple[float, float, float]
#: What a node publishes of a frame: ``(frame, t_gen, obs row, HLC stamp or None)``.
Published = tuple[int, float, NDArray[np.float64], Stamp | None]
#: ``publish(sender, kind, subject, index, payload, payload_bits, receivers)``.
Publish = Callable[[int, int, int, int, Any, int, Sequence[int]], None]


def crash_times(faults: Sequence[FaultSpec], n: int) -> list[float]:
    """Time from which each node is crashed (``inf``: never)."""
    crash_at = [math.inf] * n
    for f in faults:
        if f.kind == "crash":
            crash_at[f.node] = min(crash_at[f.node], f.start)
    return crash_at


def slow_windows(faults: Sequence[FaultSpec]) -> dict[int, list[SlowWindow]]:
    """The ``slow`` fault windows of each node (nodes without one are absent)."""
    slow: dict[int, list[SlowWindow]] = {}
    for f in faults:
        if f.kind == "slow":
            slow.setdefault(f.node, []).append((f.start, f.end, f.factor))
    return slow


class NodeRules:
    """The physics nodes' rules (docs/concepts/model.md, "Physics nodes"); transport in hooks.

    Subclasses supply :meth:`publish_state` and :meth:`republish` (how a state
    leaves the node); :meth:`cost` and :meth:`rollback` are hooks with the model's
    defaults (:func:`~sigma_des.events.jobs.job_cost`, the truth's re-simulation).

    Args:
        clock: the clock (DES kernel or live loop).
        truth: the frames the nodes publish rows of (``H``, ``slot_frame``,
            ``obs_hist[slot, i]``) and roll back (``rollback(i, c, current, row)``).
        host_of: host of every node served (an index into the hosts' cores).
        hosts: number of hosts served.
        cores_per_host: cores per host (FCFS).
        step_time: the cache of step-time draws (stream ``compute``, the run's nodes).
        faults: the injected faults (crash and slow act here).
        clocks: the run's nodes' local clocks.
        hlc: nodes keep hybrid logical clocks (the ``hlc`` method).
        warp: time-warp threshold Θ_warp in frames (None: no time warp).
        cmd: ``(m, command_dim)`` initial command rows of the nodes served.
        ids: the run's node id of every node served (None: ``0 .. m-1``).

    Attributes:
        frame: each node's last computed frame; ``req``: newest trigger received;
        target: the frame its running job computes; ``busy``: a job is running;
        rb_steps: re-simulation steps owed to the next job; ``cmd``/``cmd_stamp``:
        command rows in force and their stamps; ``last_pub``: the last state
        published; ``history_misses``: states published of a frame no longer held.
    """

    def __init__(
        self,
        *,
        clock: Clock,
        truth: Any,
        host_of: Sequence[int],
        hosts: int,
        cores_per_host: int,
        step_time: DrawCache,
        faults: Sequence[FaultSpec],
        clocks: NodeClocks,
        hlc: bool,
        warp: int | None,
        cmd: NDArray[np.float64],
        ids: Sequence[int] | None = None,
    ) -> None:
        m = len(host_of)
        self.clock = clock
        self.truth = truth
        self.ids: list[int] = list(range(m)) if ids is None else [int(g) for g in ids]
        self.host_of = list(host_of)
        self.cores: list[list[float]] = [[0.0] * cores_per_host for _ in range(hosts)]
        self.step_time = step_time
        crash = crash_times(faults, clocks.n)
        self.crash_at = [crash[g] for g in self.ids]
        self.slow = slow_windows(faults)  # by the run's node id
        self.clocks = clocks
        self.offset: list[float] = clocks.offset.tolist()
        self.drift: list[float] = (clocks.drift_ppm * 1e-6).tolist()
        self.hlc = [HLC() for _ in range(m)] if hlc else []
        self.warp = warp
        self.cmd = cmd
        self.cmd_stamp = [-1] * m
        self.frame = [-1] * m
        self.req = [-1] * m
        self.target = [-1] * m
        self.busy = [False] * m
        self.rb_steps = [0] * m
        self.last_pub: list[Published | None] = [None] * m
        self.history_misses = 0

    # ------------------------------------------------------------ hooks

    def publish_state(self, i: int, payload: Published) -> None:
        """Node ``i`` publishes its state ``payload`` to the server."""
        raise NotImplementedError

    def republish(self, i: int, index: int, payload: Published) -> None:
        """Node ``i`` answers re-request ``index`` with its last state ``payload``."""
        raise NotImplementedError

    def cost(self, i: int, target: int, now: float) -> float:
        """Seconds of compute of node ``i``'s job to ``target`` starting at ``now``."""
        g = self.ids[i]
        return job_cost(self.step_time, self.slow.get(g, ()), g, self.frame[i] + 1, target,
                        self.rb_steps[i], now)

    def rollback(self, i: int, c: int, current: int, row: NDArray[np.float64]) -> int:
        """Re-simulate node ``i`` from frame ``c``; the compute steps its next job owes."""
        return int(self.truth.rollback(i, c, current, row))

    # ------------------------------------------------------------ rules

    def local_time(self, i: int, t: float) -> float:
        """Node ``i``'s local clock at true time ``t``."""
        g = self.ids[i]
        if self.clocks.spec.ntp_period > 0:
            return float(self.clocks.local_time(g, t))
        return t + self.offset[g] + self.drift[g] * t

    def receive_trigger(self, i: int, k: int, stamp: Stamp | None, t: float) -> None:
        """Trigger ``k`` (server stamp ``stamp``) reached node ``i`` at ``t``."""
        if t >= self.crash_at[i]:
            return
        if self.hlc and stamp is not None:
            self.hlc[i].receive(self.local_time(i, t), stamp)
        self.on_trigger(i, k)

    def receive_command(self, i: int, stamp_frame: int, row: NDArray[np.float64],
                        t: float) -> None:
        """A command row stamped ``stamp_frame`` reached node ``i`` at ``t``."""
        if t < self.crash_at[i]:
            self.on_command(i, stamp_frame, row)

    def receive_rerequest(self, i: int, frame: int, index: int, t: float) -> None:
        """Lock-Step re-request ``index`` of ``frame`` reached node ``i`` at ``t``."""
        if t < self.crash_at[i]:
            self.on_rerequest(i, frame, index)

    def on_trigger(self, i: int, k: int) -> None:
        """Trigger ``k`` reached node ``i``: start (or remember) the job up to ``k``."""
        if k <= self.req[i]:
            return  # duplicate or stale trigger
        self.req[i] = k
        if not self.busy[i]:
            self.start_job(i)

    def on_rerequest(self, i: int, frame: int, index: int) -> None:
        """Lock-Step re-request of ``frame``: republish it, or compute it first."""
        last = self.last_pub[i]
        if self.frame[i] >= frame and last is not None and last[0] == frame:
            self.republish(i, index, last)
        elif self.req[i] < frame:
            self.on_trigger(i, frame)

    def start_job(self, i: int) -> None:
        """Start node ``i``'s job to its newest trigger on the first free core of its host."""
        now = self.clock.now
        target = self.req[i]
        cost = self.cost(i, target, now)
        self.rb_steps[i] = 0
        cores = self.cores[self.host_of[i]]
        free = heapq.heappop(cores)
        start = now if now > free else free
        heapq.heappush(cores, start + cost)
        self.busy[i] = True
        self.target[i] = target
        self.clock.call_at(start + cost, self.complete, i, target)

    def complete(self, i: int, target: int) -> None:
        """Node ``i``'s job to ``target`` is done: publish the frame, catch up if behind."""
        t = self.clock.now
        self.busy[i] = False
        if t >= self.crash_at[i]:
            return
        if target > self.frame[i]:
            self.frame[i] = target
            truth = self.truth
            slot = target % truth.H
            if truth.slot_frame[slot] != target:
                self.history_misses += 1
            obs = truth.obs_hist[slot, i].copy()
            stamp = self.hlc[i].send(self.local_time(i, t)) if self.hlc else None
            payload = (target, t, obs, stamp)
            self.last_pub[i] = payload
            self.publish_state(i, payload)
        if self.req[i] > self.frame[i] or self.rb_steps[i]:
            self.start_job(i)

    def on_command(self, i: int, stamp_frame: int, row: NDArray[np.float64]) -> None:
        """A command row stamped ``stamp_frame`` reached node ``i``."""
        if stamp_frame < self.cmd_stamp[i]:
            return  # an older command overtaken by a newer one
        self.cmd_stamp[i] = stamp_frame
        self.cmd[i] = row
        if self.warp is None or stamp_frame < 0:
            return
        current = self.target[i] if self.busy[i] else self.frame[i]
        if current - stamp_frame <= self.warp:
            return
        self.rb_steps[i] += self.rollback(i, stamp_frame, current, row)
        if not self.busy[i]:
            self.start_job(i)


class PhysicsNodes(NodeRules):
    """The ``n`` physics nodes of the per-message engine: the rules on the DES network.

    Args:
        publish: the network's publish (states and republished states).
        truth: the physics truth (:class:`~sigma_des.events.truth.SwarmTruth`).
        server: the server's client id (receiver of states).
        payload_bits: state payload size.
        **rules: the :class:`NodeRules` arguments (``clock``, ``host_of``, ...).
    """

    def __init__(
        self, *, publish: Publish, truth: SwarmTruth, server: int, payload_bits: int,
        **rules: Any,
    ) -> None:
        super().__init__(truth=truth, **rules)
        self.publish = publish
        self.server = server
        self.payload_bits = payload_bits

    def publish_state(self, i: int, payload: Published) -> None:
        """One STATE message to the server."""
        self.publish(i, STATE, i, payload[0], payload, self.payload_bits, (self.server,))

    def republish(self, i: int, index: int, payload: Published) -> None:
        """One REPUBLISH message to the server."""
        self.publish(i, REPUBLISH, i, index, payload, self.payload_bits, (self.server,))

    def deliver(self, i: int, kind: int, index: int, payload: Any, t: float) -> None:
        """A message reached node ``i`` at ``t`` (ignored once the node crashed)."""
        if kind == TRIGGER:
            self.receive_trigger(i, payload[0], payload[1], t)
        elif kind == COMMAND:
            self.receive_command(i, payload[0], payload[1], t)
        elif kind == REREQUEST:
            self.receive_rerequest(i, payload, index, t)

    def count_history_misses(self, misses: int) -> None:
        """Count ``misses`` more rollbacks past the history (met by the compiled core)."""
        self.history_misses += misses
