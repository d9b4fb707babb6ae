"""The physics nodes on their own: FCFS host cores, coalesced triggers, faults, rollbacks."""

from __future__ import annotations

from typing import Any

import numpy as np

from sigma_des.agents.pointmass import PointMass
from sigma_des.core.draws import DrawCache
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.events.node import PhysicsNodes
from sigma_des.events.spec import FaultSpec
from sigma_des.events.truth import SwarmTruth
from sigma_des.net.clocks import ClockSpec, NodeClocks
from sigma_des.net.kinds import COMMAND, STATE, TRIGGER

STEP = 0.001  # constant step time (s)


def _nodes(
    n: int = 3, cores: int = 2, faults: tuple[FaultSpec, ...] = (), warp: int | None = None
) -> tuple[Kernel, SwarmTruth, PhysicsNodes, list[tuple[float, int, int, int]]]:
    k = Kernel()
    dyn = PointMass()
    truth = SwarmTruth(dyn, n, 16, 30.0, checkpoints=warp is not None)
    sent: list[tuple[float, int, int, int]] = []

    def publish(sender: int, kind: int, subject: int, index: int, payload: Any, bits: int,
                to: Any) -> None:
        sent.append((k.now, sender, kind, index))

    step = DrawCache(n, lambda s, kd, i, a: np.full(len(s), STEP), constant=STEP)
    clocks = NodeClocks(ClockSpec(), RandomStreams(1).stream("clocks"), n)
    nodes = PhysicsNodes(clock=k, publish=publish, truth=truth, server=n, host_of=[0] * n,
                         hosts=1, cores_per_host=cores, step_time=step, faults=faults,
                         clocks=clocks, hlc=False, warp=warp, payload_bits=150,
                         cmd=dyn.default_command(truth.state))
    return k, truth, nodes, sent


def _trigger(k: Kernel, truth: SwarmTruth, nodes: PhysicsNodes, frame: int) -> None:
    truth.step_frame(frame, 0.01, nodes.cmd, None)
    for i in range(len(nodes.frame)):
        nodes.deliver(i, TRIGGER, frame, (frame, None), k.now)


def test_jobs_queue_on_the_host_cores_first_come_first_served() -> None:
    k, truth, nodes, sent = _nodes()
    _trigger(k, truth, nodes, 0)
    k.run(until=1.0)
    # two cores: nodes 0 and 1 compute at once, node 2 waits for the first free core
    assert sent == [(STEP, 0, STATE, 0), (STEP, 1, STATE, 0), (2 * STEP, 2, STATE, 0)]
    assert nodes.frame == [0, 0, 0] and nodes.busy == [False] * 3
    assert nodes.history_misses == 0


def test_triggers_arriving_while_busy_coalesce_into_one_catch_up_job() -> None:
    k, truth, nodes, sent = _nodes(n=1, cores=1)
    _trigger(k, truth, nodes, 0)
    k.run(until=0.0005)  # busy with frame 0 until 0.001
    _trigger(k, truth, nodes, 1)
    _trigger(k, truth, nodes, 2)
    k.run(until=1.0)
    # frame 0 at 0.001, then one job stepping frames 1 and 2: two step times
    assert sent == [(STEP, 0, STATE, 0), (STEP + 2 * STEP, 0, STATE, 2)]


def test_crash_silences_a_node_and_slow_multiplies_its_steps() -> None:
    faults = (FaultSpec(kind="crash", node=1, start=0.0005),
              FaultSpec(kind="slow", node=0, start=0.0, end=1.0, factor=3.0))
    k, truth, nodes, sent = _nodes(faults=faults)
    _trigger(k, truth, nodes, 0)
    k.run(until=1.0)
    assert sent == [(2 * STEP, 2, STATE, 0), (STEP * 3.0, 0, STATE, 0)]


def test_an_old_command_is_ignored_and_a_late_one_rolls_back() -> None:
    k, truth, nodes, sent = _nodes(n=1, cores=1, warp=2)
    for f in range(6):
        _trigger(k, truth, nodes, f)
        k.run(until=(f + 1) * 0.01)
    assert nodes.frame == [5] and truth.rollbacks == 0
    row = np.array([1.0, 2.0, 3.0])
    nodes.deliver(0, COMMAND, 0, (4, row), k.now)  # 5 - 4 <= 2: applies, no rollback
    assert truth.rollbacks == 0 and np.array_equal(nodes.cmd[0], row)
    nodes.deliver(0, COMMAND, 1, (1, row * 2), k.now)  # older stamp than 4: ignored
    assert np.array_equal(nodes.cmd[0], row) and truth.rollbacks == 0
    nodes.cmd_stamp[0] = 0
    nodes.deliver(0, COMMAND, 2, (2, row), k.now)  # 5 - 2 > 2: frames 2..5 again
    assert (truth.rollbacks, truth.resim_steps) == (1, 4)
    # the re-simulation costs a job of 4 rollback steps on the core, from now
    assert nodes.busy == [True] and nodes.target == [5]
    assert nodes.cores[0] == [(6 * 0.01) + (((STEP + STEP) + STEP) + STEP)]
    published = len(sent)
    k.run(until=1.0)
    assert len(sent) == published  # frame 5 was published already: not again
    assert nodes.busy == [False] and nodes.rb_steps == [0]
