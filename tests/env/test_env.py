"""The swarm envs: PettingZoo conformance, seeds, scene isolation, bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from sigma_des.env import SwarmEnv, SwarmVec, SwarmVectorEnv
from sigma_des.errors import ConfigError

SMALL = {"nodes": 3}


def _rollout(env: SwarmEnv, seed: int, steps: int) -> list[tuple]:
    obs, _ = env.reset(seed=seed)
    out = [tuple(np.concatenate([obs[a] for a in env.possible_agents]).tolist())]
    rng = np.random.default_rng(0)  # actions: same sequence for both rollouts
    for _ in range(steps):
        acts = {a: rng.uniform(-1, 1, 3).astype(np.float32) for a in env.agents}
        obs, r, te, tr, info = env.step(acts)
        out.append(tuple(np.concatenate([obs[a] for a in env.possible_agents]).tolist())
                   + tuple(r.values()) + tuple(i["aoi"] for i in info.values()))
        if not env.agents:
            break
    return out


def test_parallel_api_test_passes() -> None:
    env = SwarmEnv(scenario=SMALL, max_steps=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the test's own reset option {"options": 1}
        parallel_api_test(env, num_cycles=40)


def test_pettingzoo_seed_test_passes() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parallel_seed_test(lambda: SwarmEnv(task="goal", scenario=SMALL, max_steps=20))


def test_default_env_is_the_small_formation() -> None:
    env = SwarmEnv()
    assert env.possible_agents == ["node_1", "node_2", "node_3", "node_4"]
    obs, infos = env.reset(seed=3)
    assert obs["node_1"].shape == (9,) and obs["node_1"].dtype == np.float32
    # the followers start in their slots: zero slot error in the first observation
    np.testing.assert_allclose(np.stack([o[:3] for o in obs.values()]), 0.0, atol=1e-9)
    assert all(i["aoi"] > 0 for i in infos.values())  # a delayed view, not the truth


def test_same_seed_same_episode_different_seed_differs() -> None:
    a = _rollout(SwarmEnv(scenario=SMALL, max_steps=15), 7, 15)
    b = _rollout(SwarmEnv(scenario=SMALL, max_steps=15), 7, 15)
    c = _rollout(SwarmEnv(scenario=SMALL, max_steps=15), 8, 15)
    assert a == b
    assert a != c


def test_goal_task_reward_improves_when_flying_to_the_goal() -> None:
    env = SwarmEnv(task="goal", scenario=SMALL, max_steps=40)
    obs, _ = env.reset(seed=1)
    first = last = None
    for _ in range(40):
        # fly towards the goal: action = clipped goal offset (obs[0:2] = offset / radius)
        acts = {a: np.clip(np.r_[obs[a][:2] * 2.0, 0.0], -1, 1).astype(np.float32)
                for a in env.agents}
        obs, r, te, tr, info = env.step(acts)
        first = r if first is None else first
        last = r
        if not env.agents:
            break
    assert not any(te.values())
    assert sum(last.values()) > sum(first.values()) + 0.1


@pytest.mark.parametrize("method", ["none", "lockstep", "bides"])
def test_a_scene_does_not_depend_on_how_many_scenes_run(method: str) -> None:
    rng = np.random.default_rng(1)
    acts = rng.uniform(-0.5, 0.5, (12, 3, 2, 3))
    one = SwarmVec(method=method, n_scenes=1, scenario=SMALL, max_steps=8)
    three = SwarmVec(method=method, n_scenes=3, scenario=SMALL, max_steps=8)
    o1, _ = one.reset(seed=5)
    o3, _ = three.reset(seed=5)
    np.testing.assert_array_equal(o1[0], o3[0])
    for k in range(12):  # past max_steps: scene 0 autoresets in both
        r1 = one.step(acts[k, :1])
        r3 = three.step(acts[k])
        for x, y in zip(r1[:4], r3[:4], strict=True):
            np.testing.assert_array_equal(x[0], y[0])
        np.testing.assert_array_equal(r1[4]["aoi"][0], r3[4]["aoi"][0])
    assert three.batch.episode[0] == 1  # the autoreset happened


def test_scenes_differ_from_each_other() -> None:
    vec = SwarmVec(task="goal", n_scenes=2, scenario=SMALL, max_steps=5)
    obs, _ = vec.reset(seed=2)
    assert not np.array_equal(obs[0], obs[1])  # each scene draws its own goals


def test_gymnasium_vector_adapter_flattens_scene_major() -> None:
    env = SwarmVectorEnv(n_scenes=2, scenario=SMALL, max_steps=5)
    assert env.num_envs == 4
    obs, infos = env.reset(seed=1)
    assert obs.shape == (4, 9) and env.observation_space.contains(obs)
    acts = np.zeros((4, 3), dtype=np.float32)
    obs2, r, te, tr, infos = env.step(acts)
    assert r.shape == (4,) and te.dtype == bool and infos["aoi"].shape == (4,)
    ref = SwarmVec(n_scenes=2, scenario=SMALL, max_steps=5)
    ref.reset(seed=1)
    o, rr, *_ = ref.step(np.zeros((2, 2, 3)))
    np.testing.assert_array_equal(obs2, o.reshape(4, 9))
    np.testing.assert_array_equal(r, rr.reshape(4))


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.zeros(2, dtype=np.float32), "node_1: action shape"),
        (np.zeros(3, dtype=np.int64), "node_1: action dtype"),
        (np.array([0.0, np.nan, 0.0]), r"node_1: action\[1\] is nan"),
        (np.array([0.0, 0.0, 1.5]), r"node_1: action\[2\] = 1.5 outside"),
    ],
)
def test_bad_actions_are_named_and_leave_the_env_intact(action: np.ndarray, match: str) -> None:
    good = {"node_1": np.full(3, 0.3), "node_2": np.full(3, -0.2)}
    env = SwarmEnv(scenario=SMALL, max_steps=5)
    ref = SwarmEnv(scenario=SMALL, max_steps=5)
    env.reset(seed=4)
    ref.reset(seed=4)
    with pytest.raises(ValueError, match=match):
        env.step({**good, "node_1": action})
    a = env.step(good)
    b = ref.step(good)
    assert a[1] == b[1]
    np.testing.assert_array_equal(a[0]["node_2"], b[0]["node_2"])


def test_missing_unknown_and_finished_agents_and_episode() -> None:
    env = SwarmEnv(scenario=SMALL, max_steps=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
    env.reset(seed=1)
    with pytest.raises(ValueError, match="node_2: missing action"):
        env.step({"node_1": np.zeros(3)})
    with pytest.raises(ValueError, match="unknown agent 'node_9'"):
        env.step({"node_1": np.zeros(3), "node_2": np.zeros(3), "node_9": np.zeros(3)})
    for _ in range(2):
        *_, tr, _i = env.step({"node_1": np.zeros(3), "node_2": np.zeros(3)})
    assert all(tr.values()) and env.agents == []
    with pytest.raises(RuntimeError, match="finished episode"):
        env.step({"node_1": np.zeros(3)})


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"task": "hover"}, "task: unknown task 'hover'"),
        ({"method": "magic"}, "method: unknown method"),
        ({"task_params": {"dd": 3.0}}, "task.dd: unknown key"),
        ({"task_params": {"d": -1.0}}, "task.d: must be"),
        ({"scenario": {"nodez": 3}}, "nodez"),
        ({"scenario": {"duration": 3.0}}, "duration: is set by the env"),
        ({"max_steps": 0}, "max_steps: must be an integer >= 1"),
        ({"scenario": {"nodes": 1}}, "nodes: the formation task needs at least 2"),
    ],
)
def test_bad_options_raise_naming_the_field(kwargs: dict, key: str) -> None:
    with pytest.raises(ValueError, match=key):
        SwarmEnv(**kwargs)
    assert issubclass(ConfigError, ValueError)


def test_a_scene_that_never_shows_a_state_is_truncated_not_crashed() -> None:
    # 5 s links: no state reaches the server before the scenario ends (2.1 s)
    env = SwarmEnv(scenario={**SMALL, "net.host_link.latency": 5.0}, max_steps=1)
    obs, infos = env.reset(seed=1)
    assert all((o == 0).all() for o in obs.values())
    assert all(np.isnan(i["aoi"]) for i in infos.values())
    _, _, te, tr, _ = env.step({a: np.zeros(3) for a in env.agents})
    assert all(tr.values()) and not any(te.values()) and env.agents == []


def test_tight_task_observes_the_ages_the_env_reports() -> None:
    from sigma_des.env.tasks import AGE_REF

    kw = {"task": "tight", "scenario": {"nodes": 3, "net.host_link.latency": 0.05},
          "max_steps": 5}
    vec = SwarmVec(**kw)
    obs, infos = vec.reset(seed=2)
    for _ in range(3):
        np.testing.assert_allclose(obs[0, :, 5] * AGE_REF, infos["aoi"][0], rtol=1e-6)
        assert (infos["aoi"][0] > 0.05).all()  # at least the one-way link latency
        obs, _, _, _, infos = vec.step(np.zeros((1, 2, 3)))
    perfect = SwarmVec(perfect_info=True, **kw)
    obs, _ = perfect.reset(seed=2)
    assert obs.shape == (1, 2, 14) and (obs[0][:, [5, 8, 13]] == 0).all()
