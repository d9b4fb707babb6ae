"""Tasks: observation layout, command mapping and reward on hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.agents.pointmass import PointMass
from sigma_des.core.models import SwarmView
from sigma_des.core.rng import Stream
from sigma_des.env.controllers import extrapolating, naive
from sigma_des.env.tasks import FormationTask, GoalTask, TightTask, make_task

D = 15.0
S = D * math.sqrt(0.5)  # slot offsets of a 45-degree V: (-S, +S) rank 1, (-S, -S) rank 2


def _obs(rows: list[tuple[float, float, float, float, float]]) -> np.ndarray:
    """(n, 12) published states from (x, y, h, speed, psi)."""
    o = np.zeros((len(rows), 12))
    for i, (x, y, h, v, psi) in enumerate(rows):
        o[i, [9, 10, 11, 0, 5]] = x, y, h, v, psi
    return o


def test_formation_reward_hand_computed() -> None:
    task = FormationTask()
    truth = _obs([(0, 0, 100, 10, 0), (-S + 3, S, 100, 10, 0), (-S, -S, 104, 10, 0)])
    acts = np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    r, fail, e = task.reward(truth, None, 0.0, [1, 2], acts)
    np.testing.assert_allclose(e, [3.0, 4.0])
    # -(e/d)^2 - w_u |a|^2 / 3 (every node farther apart than r_safe = 5 m)
    np.testing.assert_allclose(r, [-(3 / 15) ** 2 - 0.01 * 0.09 / 3, -(4 / 15) ** 2])
    assert not fail.any()


def test_formation_collision_and_divergence_fail_with_penalty() -> None:
    task = FormationTask()
    truth = _obs([(0, 0, 100, 10, 0), (0.5, 0, 100, 10, 0), (-S - 80, -S, 100, 10, 0)])
    r, fail, e = task.reward(truth, None, 0.0, [1, 2], np.zeros((2, 3)))
    assert fail.tolist() == [True, True]  # node 1 collides (0.5 m), node 2 is 80 m > 75 m off
    e1 = math.hypot(S + 0.5, S)
    np.testing.assert_allclose(r[0], -(e1 / D) ** 2 - (1 - 0.5 / 5) ** 2 - 10.0)
    np.testing.assert_allclose(r[1], -(75 / D) ** 2 - 10.0)  # error clipped at div * d


def test_formation_observation_layout() -> None:
    task = FormationTask()
    shown = _obs([(0, 0, 100, 10, 0), (-S + 3, S, 98, 5, math.pi / 2), (-S, -S, 100, 10, 0)])
    view = SwarmView(obs=shown, frame=np.array([4, 4, 4]), valid=np.array([True, True, True]),
                     aligned_frame=4)
    o = task.observe(view, None, 0.0, [1, 2])
    # node 1: slot error (-3, 0)/d, altitude error +2/10, leader velocity (1, 0),
    # own velocity (0, 0.5), nearest neighbour offset / d
    np.testing.assert_allclose(o[0, :7], [-3 / D, 0.0, 0.2, 1.0, 0.0, 0.0, 0.5], atol=1e-6)
    rel = shown[0, 9:11] - shown[1, 9:11]  # the leader is node 1's nearest neighbour
    np.testing.assert_allclose(o[0, 7:], rel / D, atol=1e-6)
    assert o.dtype == np.float32


def test_invalid_rows_observe_zeros_and_send_no_command() -> None:
    task = FormationTask()
    shown = _obs([(0, 0, 100, 10, 0), (-S, S, 100, 10, 0), (0, 0, 0, 0, 0)])
    shown[2] = np.nan
    view = SwarmView(obs=shown, frame=np.array([4, 4, -1]),
                     valid=np.array([True, True, False]), aligned_frame=4)
    o = task.observe(view, None, 0.0, [1, 2])
    assert (o[1] == 0).all()
    task_ = FormationTask(turn_max=0.0)  # the leader's route: straight on its start heading
    ep = {"psi0": 0.0, "h0": 100.0, "stream": Stream(1, "env.formation")}
    nodes, cmds = task_.commands(np.array([[0.5, 0.5, 0.1], [0.0, 0.0, 0.0]]), view, ep, 0.0,
                                 [1, 2], PointMass())
    assert nodes.tolist() == [0, 1]  # leader (scripted) and node 1; node 2 has no shown state
    np.testing.assert_allclose(cmds[0], [10.0, 0.0, 0.0], atol=1e-12)  # north at 10 m/s, level
    # node 1: (vn, ve) = (10, 10) m/s, climb towards +1 m: 0.5 1/s x 1 m
    np.testing.assert_allclose(cmds[1], [10.0, 10.0, 0.5], atol=1e-12)


def test_goal_task_and_unknown_names() -> None:
    task = GoalTask()
    ep = {"goal": np.array([[10.0, 0.0, 100.0], [0.0, 0.0, 100.0]])}
    truth = _obs([(0, 0, 100, 0, 0), (0, 20, 100, 0, 0)])
    r, fail, e = task.reward(truth, ep, 0.0, [0, 1], np.zeros((2, 3)))
    np.testing.assert_allclose(e, [10.0, 20.0])
    np.testing.assert_allclose(r, [-(10 / 20) ** 2, -(20 / 20) ** 2])
    with pytest.raises(ValueError, match="task: unknown task 'x'"):
        make_task("x")
    with pytest.raises(ValueError, match="task.radius: must be > 0"):
        make_task("goal", {"radius": 0.0})


def test_tight_observation_carries_ages_and_velocities() -> None:
    task = make_task("tight")
    assert isinstance(task, TightTask) and task.obs_dim == 14
    d = task.d
    s = d * math.sqrt(0.5)
    # leader north at 15 m/s; node 1 in its slot flying east at 5 m/s; node 2 slot + (1, 0)
    shown = _obs([(0, 0, 100, 15, 0), (-s, s, 100, 5, math.pi / 2), (-s + 1, -s, 97, 10, 0)])
    view = SwarmView(obs=shown, frame=np.array([4, 4, 4]), valid=np.array([True, True, True]),
                     aligned_frame=4)
    age = np.array([0.2, 0.05, 0.3])
    o = task.observe(view, None, 0.0, [1, 2], age)
    rel1 = (shown[0, 9:11] - shown[1, 9:11]) / d  # node 1's nearest: the leader
    np.testing.assert_allclose(
        o[0], [0, 0, 0, 0, 0.5, 0.5, 1.5, 0, 2.0, *rel1, 1.5, 0, 2.0], atol=1e-6)
    rel2 = (shown[0, 9:11] - shown[2, 9:11]) / d  # node 2's nearest: the leader too
    np.testing.assert_allclose(
        o[1], [-1 / d, 0, 0.3, 1.0, 0, 3.0, 1.5, 0, 2.0, *rel2, 1.5, 0, 2.0], atol=1e-6)
    # no ages given (perfect information): age columns are 0
    z = task.observe(view, None, 0.0, [1, 2])
    assert (z[:, [5, 8, 13]] == 0).all()
    np.testing.assert_array_equal(np.delete(z, [5, 8, 13], 1), np.delete(o, [5, 8, 13], 1))


def test_controllers_hand_computed() -> None:
    task = make_task("tight")
    assert isinstance(task, TightTask)
    o = np.zeros((1, 1, 14), dtype=np.float32)
    o[0, 0, [0, 2, 3, 5, 6, 8]] = [0.5, 0.1, 1.0, 1.0, 1.5, 2.0]
    # slot error 3 m north, 1 m up; own velocity 10 m/s north, age 0.1 s; leader 15 m/s
    # north, age 0.2 s. naive: v = 15 + 1 * 3 = 18 m/s -> 0.9; dh = 1 m / 10 m
    np.testing.assert_allclose(naive(o, task)[0, 0], [0.9, 0.0, 0.1], atol=1e-6)
    # extrapolating (lead = own age 0.1 s): e = 3 + 15 * 0.3 - 10 * 0.2 = 5.5 -> 20.5 / 20
    np.testing.assert_allclose(extrapolating(o, task)[0, 0], [1.0, 0.0, 0.1], atol=1e-6)
    o[0, 0, 0] = 0.0
    np.testing.assert_allclose(extrapolating(o, task)[0, 0], [17.5 / 20, 0.0, 0.1], atol=1e-6)
    o[0, 0, [5, 8]] = 0.0  # ages 0: the two controllers agree
    np.testing.assert_array_equal(naive(o, task), extrapolating(o, task))


@pytest.mark.parametrize("task", [FormationTask(), TightTask()])
def test_leader_heading_from_kept_turns_equals_fresh_draws(task: FormationTask) -> None:
    """The route's turn rates are drawn once per episode and kept (a longer prefix when
    the episode outgrows them): every heading has the bits of drawing them afresh."""
    stream = Stream(11, "env.route")
    ep = task.episode(stream, np.array([[10.0, 0, 0, 0, 0, 0.3, 0, 0, 0, 0, 0, 100.0]]))
    for t in [0.0, 0.05, 1.7, 0.4, 33.05, 2.0, 99.99, 150.0, 7.3]:
        m = int(t // task.segment)
        w = task.turn_max * (2.0 * stream.uniform(np.arange(m + 1)) - 1.0)
        want = float(0.3 + task.segment * w[:m].sum() + (t - m * task.segment) * w[m])
        assert task._heading(ep, t) == want
    assert ep["turns"].size >= 151 / task.segment  # grew past its first 32 segments
