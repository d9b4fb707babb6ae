"""The compiled scene-axis observation and reward give the numpy path's bits.

``FormationTask`` and ``TightTask`` compute ``observe_many`` and ``reward_many`` in
``sigma_des.env.task_kernels``; ``Task``'s own methods (the numpy expressions GoalTask
uses) are the reference. ``commands_many`` of a velocity-commanded model is compiled
around numpy's trigonometry; each scene's ``commands`` (through ``to_command``) is the
reference. Cases are random swarms with the awkward values in them: rows
with no shown state (NaN) and invalid rows, infinite positions, NaN ages, coincident
nodes, collisions and divergences. Bits are compared, not values (-0.0 is not 0.0),
except that a NaN is any NaN (which operand's NaN an operation passes on, and so its
sign bit, is the compiler's choice).
"""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents.pointmass import PointMass
from sigma_des.core.models import SwarmView
from sigma_des.core.rng import RandomStreams
from sigma_des.env.tasks import FormationTask, GoalTask, Task, TightTask


def _swarms(seed: int, S: int = 12, n: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    obs = rng.normal(0.0, 1.0, (S, n, 12))
    obs[..., 0] = rng.uniform(0.0, 25.0, (S, n))  # speed
    obs[..., 5] = rng.uniform(-4.0, 4.0, (S, n))  # heading
    obs[..., 9:12] = rng.normal(0.0, 8.0, (S, n, 3))
    obs[0, 2] = np.nan  # a node with no shown state
    obs[1, 0] = np.nan  # the leader unknown
    obs[2, 3, 9] = np.inf
    obs[3, 1, 10] = -np.inf
    obs[4, 2, 9:12] = obs[4, 1, 9:12]  # two nodes in the same place
    obs[5, :, 9:12] *= 1e3  # far beyond the clip
    valid = rng.uniform(size=(S, n)) > 0.2
    age = rng.uniform(0.0, 0.5, (S, n))
    age[~valid] = np.nan
    age[6, 0] = np.inf
    return obs, valid, age


def _same(x: np.ndarray, y: np.ndarray) -> bool:
    """Equal bits, NaN where NaN."""
    if x.dtype.kind != "f":
        return x.tobytes() == y.tobytes()
    nan = np.isnan(x)
    return bool((nan == np.isnan(y)).all()) and x[~nan].tobytes() == y[~nan].tobytes()


@pytest.mark.parametrize("task", [FormationTask(), TightTask(), FormationTask(d=9.0, theta_deg=30)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_compiled_observation_is_the_numpy_one_bit_for_bit(task: Task, seed: int) -> None:
    obs, valid, age = _swarms(seed)
    agents = task.agents(obs.shape[1])
    t = np.zeros(obs.shape[0])
    got = task.observe_many(obs, valid, [None] * len(t), t, agents, age)
    want = Task.observe_many(task, obs, valid, [None] * len(t), t, agents, age)
    assert got.dtype == want.dtype == np.float32 and got.shape == want.shape
    assert _same(got, want)
    # the cases reach the clip, the zeroed rows and the NaN columns
    assert (np.abs(want) == 10.0).any() and (want == 0.0).all(axis=2).any()
    no_age = task.observe_many(obs, valid, [None] * len(t), t, agents, None)
    assert _same(no_age, Task.observe_many(task, obs, valid, [None] * len(t), t, agents, None))


@pytest.mark.parametrize("task", [FormationTask(), TightTask()])
@pytest.mark.parametrize("seed", [0, 3])
def test_the_compiled_reward_is_the_numpy_one_bit_for_bit(task: Task, seed: int) -> None:
    truth, _, _ = _swarms(seed)
    truth[7, 3, 9:12] = truth[7, 4, 9:12] + 0.5  # a collision
    truth[8, 2, 9:12] += 500.0  # a divergence
    agents = task.agents(truth.shape[1])
    rng = np.random.default_rng(seed + 10)
    actions = rng.uniform(-1.0, 1.0, (truth.shape[0], len(agents), 3))
    t = np.zeros(truth.shape[0])
    got = task.reward_many(truth, [None] * len(t), t, agents, actions)
    want = Task.reward_many(task, truth, [None] * len(t), t, agents, actions)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape
        assert _same(g, w)
    r, fail, e = want
    assert fail.any() and not fail.all() and np.isnan(e).any()
    assert fail[7].any() and fail[8].any()


@pytest.mark.parametrize("task", [FormationTask(), TightTask(), GoalTask()])
@pytest.mark.parametrize("seed", [0, 4])
def test_the_compiled_commands_are_each_scenes_numpy_commands_bit_for_bit(task: Task,
                                                                          seed: int) -> None:
    obs, valid, _ = _swarms(seed)
    obs[7, :, 11] = np.random.default_rng(seed).normal(0.0, 30.0, obs.shape[1])
    S, n = obs.shape[:2]
    dyn = PointMass()
    agents = task.agents(n)
    rng = np.random.default_rng(seed + 20)
    actions = rng.uniform(-1.0, 1.0, (S, len(agents), 3))
    actions[2, 0] = (-1.0, -0.0, 1.0)  # a full action, a negative zero
    t = np.asarray(rng.uniform(0.0, 30.0, S))
    eps = [task.episode(RandomStreams(seed + s).stream("env.route"), obs[0]) for s in range(S)]
    send, cmds = task.commands_many(actions, obs, valid, eps, t, agents, dyn)
    assert send.shape == (S, n) and cmds.shape == (S, n, 3) and cmds.dtype == np.float64
    for s in range(S):
        view = SwarmView(obs=obs[s], frame=np.zeros(n, dtype=np.int64), valid=valid[s],
                         aligned_frame=0)
        nodes, want = task.commands(actions[s], view, eps[s], float(t[s]), agents, dyn)
        assert np.array_equal(np.flatnonzero(send[s]), nodes)
        assert _same(cmds[s], want)
    # the cases reach unsent rows, both altitude limits and the free range between them
    assert send.any() and not send.all()
    vh = cmds[..., 2][send]
    assert (vh == 3.0).any() and (vh == -3.0).any() and (np.abs(vh) < 3.0).any()
