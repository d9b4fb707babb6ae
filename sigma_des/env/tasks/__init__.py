"""Learning tasks of the swarm environment: observation, action, reward, termination.

A task turns what the distributed loop delivers (the *aligned* swarm view of the
alignment server, :class:`~sigma_des.core.models.SwarmView`) into per-agent
observations, the agents' actions into command rows that travel to the nodes, and
the *true* swarm state (the physics at the latest frame) into rewards and
terminations. Observations see the network; rewards see the truth.

Action (every task): ``a in [-1, 1]^3`` per agent = desired north and east velocity
``(a0, a1) * v_max`` (m/s) and an altitude change ``a2 * dh_max`` (m) from the
agent's shown altitude, sent as the guidance row ``[v, chi, h, nan]`` (the autopilot's
guidance interface, one level above the paper's attitude and throttle).

Tasks (the shared pipeline in :mod:`~sigma_des.env.tasks.base`):

* :class:`FormationTask` (the paper's demonstration): node 0, the leader, flies a
  random route per episode (stream ``env.route``; its commands travel over the
  network too); nodes ``1..n-1`` are the agents and keep the V-slots. Observation (9 columns,
  clipped to [-10, 10], from the shown states): slot error, altitude error to the
  leader, leader and own velocity, nearest neighbour's offset. Reward per agent:
  ``-(e / d)^2 - w_sep max(0, 1 - d_min / r_safe)^2 - w_u |a|^2 / 3`` (``e`` the true
  slot error clipped at ``div * d``); ``-penalty`` more for a collision or a
  divergence, which terminates every agent.
* :class:`GoalTask` (quick tests): every node flies to its own goal (7 columns);
  reward ``-(e / radius)^2`` plus the same separation, effort and ending terms.
* :class:`TightTask` (delay matters by construction): a fast, sharply turning leader
  and 6 m slots; the observation adds the *age* of every shown state it uses (14).

An agent whose own state has not been shown yet observes zeros and sends nothing.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from sigma_des.env.tasks.base import ACTION_DIM, AGE_REF, OBS_CLIP, Task
from sigma_des.env.tasks.formation import FormationTask, TightTask
from sigma_des.env.tasks.goal import GoalTask
from sigma_des.errors import ConfigError

__all__ = ["TASKS", "Task", "FormationTask", "GoalTask", "TightTask", "make_task", "ACTION_DIM",
           "AGE_REF", "OBS_CLIP"]


#: Task name -> class.
TASKS: dict[str, type[Task]] = {"formation": FormationTask, "goal": GoalTask,
                                "tight": TightTask}


def make_task(name: str, params: dict[str, Any] | None = None) -> Task:
    """The task called ``name`` with ``params`` (unknown names and keys are errors)."""
    if name not in TASKS:
        raise ConfigError("task", f"unknown task {name!r}; allowed: {sorted(TASKS)}")
    cls = TASKS[name]
    allowed = {f.name for f in fields(cls)}
    for k in params or {}:
        if k not in allowed:
            raise ConfigError(f"task.{k}", f"unknown key for task {name!r}; allowed: "
                              f"{sorted(allowed)}")
    return cls(**(params or {}))
