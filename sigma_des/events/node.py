"""The physics nodes: jobs on host cores, commands, time-warp rollbacks, published states.

Each node (docs/MODEL.md, "Physics nodes") computes one job at a time: on
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
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.core.sim import Kernel
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.events.jobs import job_cost
from sigma_des.events.spec import FaultSpec
from sigma_des.events.truth import SwarmTruth
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER

__all__ = ["PhysicsNodes", "crash_times", "slow_windows"]

#: A ``slow`` fault window: (start, end, factor).
SlowWindow = tuple[float, float, float]
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


class PhysicsNodes:
    """The ``n`` physics nodes of the per-message engine.

    Args:
        kernel: the simulation kernel (``now`` and ``at``).
        publish: the network's publish (states and republished states).
        truth: the physics truth the nodes publish rows of and roll back.
        server: the server's client id (receiver of states).
        host_of: host of every node.
        hosts: number of physics hosts.
        cores_per_host: cores per host (FCFS).
        step_time: the cache of step-time draws (stream ``compute``).
        faults: the injected faults (crash and slow act here).
        clocks: the nodes' local clocks.
        hlc: nodes keep hybrid logical clocks (the ``hlc`` method).
        warp: time-warp threshold Θ_warp in frames (None: no time warp).
        payload_bits: state payload size.
        cmd: ``(n, command_dim)`` initial command rows (the dynamics' defaults).

    Attributes:
        frame: each node's last computed frame; ``req``: newest trigger received;
        target: the frame its running job computes; ``busy``: a job is running;
        rb_steps: re-simulation steps owed to the next job; ``cmd``/``cmd_stamp``:
        command rows in force and their stamps; ``history_misses``: states
        published of a frame no longer in the truth ring.
    """

    def __init__(
        self,
        kernel: Kernel,
        publish: Publish,
        truth: SwarmTruth,
        server: int,
        host_of: Sequence[int],
        hosts: int,
        cores_per_host: int,
        step_time: DrawCache,
        faults: Sequence[FaultSpec],
        clocks: NodeClocks,
        hlc: bool,
        warp: int | None,
        payload_bits: int,
        cmd: NDArray[np.float64],
    ) -> None:
        n = len(host_of)
        self.kernel = kernel
        self.publish = publish
        self.truth = truth
        self.server = server
        self.host_of = list(host_of)
        self.cores: list[list[float]] = [[0.0] * cores_per_host for _ in range(hosts)]
        self.step_time = step_time
        self.crash_at = crash_times(faults, n)
        self.slow = slow_windows(faults)
        self.clocks = clocks
        self.offset: list[float] = clocks.offset.tolist()
        self.drift: list[float] = (clocks.drift_ppm * 1e-6).tolist()
        self.hlc = [HLC() for _ in range(n)] if hlc else []
        self.warp = warp
        self.payload_bits = payload_bits
        self.cmd = cmd
        self.cmd_stamp = [-1] * n
        self.frame = [-1] * n
        self.req = [-1] * n
        self.target = [-1] * n
        self.busy = [False] * n
        self.rb_steps = [0] * n
        self.last_pub: list[tuple[int, float, NDArray[np.float64], Stamp | None] | None] = [
            None
        ] * n
        self.history_misses = 0

    def local_time(self, i: int, t: float) -> float:
        """Node ``i``'s local clock at true time ``t``."""
        if self.clocks.spec.ntp_period > 0:
            return float(self.clocks.local_time(i, t))
        return t + self.offset[i] + self.drift[i] * t

    def deliver(self, i: int, kind: int, index: int, payload: Any, t: float) -> None:
        """A message reached node ``i`` at ``t`` (ignored once the node crashed)."""
        if t >= self.crash_at[i]:
            return
        if kind == TRIGGER:
            k, stamp = payload
            if self.hlc:
                self.hlc[i].receive(self.local_time(i, t), stamp)
            self.on_trigger(i, k)
        elif kind == COMMAND:
            self.on_command(i, *payload)
        elif kind == REREQUEST:
            self.on_rerequest(i, payload, index)

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
            self.publish(i, REPUBLISH, i, index, last, self.payload_bits, (self.server,))
        elif self.req[i] < frame:
            self.on_trigger(i, frame)

    def start_job(self, i: int) -> None:
        """Start node ``i``'s job to its newest trigger on the first free core of its host."""
        now = self.kernel.now
        target = self.req[i]
        cost = job_cost(
            self.step_time, self.slow.get(i, ()), i, self.frame[i] + 1, target, self.rb_steps[i],
            now,
        )
        self.rb_steps[i] = 0
        cores = self.cores[self.host_of[i]]
        free = heapq.heappop(cores)
        start = now if now > free else free
        heapq.heappush(cores, start + cost)
        self.busy[i] = True
        self.target[i] = target
        self.kernel.at(start + cost, self.complete, i, target)

    def complete(self, i: int, target: int) -> None:
        """Node ``i``'s job to ``target`` is done: publish the frame, catch up if behind."""
        t = self.kernel.now
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
            self.publish(i, STATE, i, target, payload, self.payload_bits, (self.server,))
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
        self.rb_steps[i] += self.truth.rollback(i, stamp_frame, current, row)
        if not self.busy[i]:
            self.start_job(i)

    def count_history_misses(self, misses: int) -> None:
        """Count ``misses`` more rollbacks past the history (met by the compiled core)."""
        self.history_misses += misses
