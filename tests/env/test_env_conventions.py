"""Gymnasium/PettingZoo conventions: per-scene seeds, ``reset_mask``, ``render_mode``,
``state_space`` — each checked against exact replays of lone or fully reset scenes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from gymnasium.wrappers.vector import RecordEpisodeStatistics
from pettingzoo.test.state_test import test_parallel_env as state_parallel_test

from sigma_des.env import SwarmEnv, SwarmVec, SwarmVectorEnv

KW: dict[str, Any] = {"scenario": {"nodes": 3}, "max_steps": 4}


def _acts(steps: int, S: int) -> np.ndarray:
    return np.random.default_rng(1).uniform(-0.5, 0.5, (steps, S, 2, 3))


def _rewards(env: SwarmVec, acts: np.ndarray) -> list[np.ndarray]:
    return [env.step(a)[1] for a in acts]


def test_a_seed_list_gives_each_scene_its_own_root() -> None:
    acts = _acts(3, 3)
    env = SwarmVec(n_scenes=3, seed=5, **KW)
    env.reset(seed=[4, 9, None])  # first reset: None = the construction seed
    assert env.batch.roots == [4, 9, 5] and env.batch.episode == [0, 0, 0]
    got = np.stack(_rewards(env, acts))
    for root, s in ((4, 0), (9, 1), (5, 2)):
        ref = SwarmVec(n_scenes=3, **KW)
        ref.reset(seed=root)
        want = np.stack(_rewards(ref, acts))
        assert np.array_equal(got[:, s], want[:, s])
    assert not np.array_equal(got[:, 0], got[:, 1])
    # a list of equal entries is the int; None later = the scene's next episode
    env.reset(seed=[None, 9, None])
    assert env.batch.roots == [4, 9, 5] and env.batch.episode == [1, 0, 1]


def test_bad_seed_lists_and_options_are_named() -> None:
    env = SwarmVec(n_scenes=2, **KW)
    with pytest.raises(ValueError, match=r"^seed: a list needs one entry per scene \(2\), "
                       r"got 3$"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match=r"^seed\[1\]: must be a non-negative int or None, "
                       r"got -2$"):
        env.reset(seed=[1, -2])
    with pytest.raises(ValueError, match=r"^options: unknown reset options \['x'\]"):
        env.reset(options={"x": 1})
    with pytest.raises(ValueError, match=r"^options\['reset_mask'\]: the first reset must "
                       "reset every scene$"):
        env.reset(options={"reset_mask": np.array([True, False])})
    env.reset(seed=0)
    with pytest.raises(TypeError, match=r"^options\['reset_mask'\]: must be a numpy array of "
                       "dtype bool, got list$"):
        env.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ValueError, match=r"^options\['reset_mask'\]: must have shape \(2,\), "
                       r"got \(3,\)$"):
        env.reset(options={"reset_mask": np.ones(3, dtype=bool)})
    with pytest.raises(ValueError, match="at least one True"):
        env.reset(options={"reset_mask": np.zeros(2, dtype=bool)})
    vec = SwarmVectorEnv(n_scenes=2, **KW)
    with pytest.raises(ValueError, match=r"^options\['reset_mask'\]: the 2 agents of scene 1 "
                       r"share it and must agree, got \[True, False\]$"):
        vec.reset(seed=0, options={"reset_mask": np.array([False, False, True, False])})


def test_reset_mask_restarts_only_the_masked_scenes_in_disabled_mode() -> None:
    acts = _acts(6, 3)
    ref = SwarmVec(n_scenes=3, autoreset="disabled", **KW)  # every scene, full resets
    ref.reset(seed=2)
    ep0 = np.stack(_rewards(ref, acts[:4]))
    ref.reset()
    ep1 = np.stack(_rewards(ref, acts[2:6]))  # scene 1's episode 1 is stepped with these
    env = SwarmVec(n_scenes=3, autoreset="disabled", **KW)
    env.reset(seed=2)
    r = _rewards(env, acts[:2])
    obs_before = env._observe_all()
    obs, infos = env.reset(options={"reset_mask": np.array([False, True, False])})
    assert np.array_equal(obs[[0, 2]], obs_before[[0, 2]])  # unmasked: unchanged
    assert env.batch.episode == [0, 1, 0] and env.steps.tolist() == [2, 0, 2]
    assert np.isnan(infos["error"]).all()
    for k in (2, 3):
        _, rew, te, tr, _ = env.step(acts[k])
        r.append(rew)
    assert tr[:, 0].tolist() == [True, False, True] and not te.any()
    got = np.stack(r)
    assert np.array_equal(got[:, [0, 2]], ep0[:, [0, 2]])
    assert np.array_equal(got[:2, 1], ep0[:2, 1]) and np.array_equal(got[2:, 1], ep1[:2, 1])
    with pytest.raises(RuntimeError, match="^scene 0: the episode is finished"):
        env.step(acts[4])
    env.reset(options={"reset_mask": np.array([True, False, True])})
    for k in (4, 5):
        _, rew, te, tr, _ = env.step(acts[k])
    assert tr[:, 0].tolist() == [False, True, False]
    assert np.array_equal(rew[1], ep1[3, 1])


def test_record_episode_statistics_with_partial_resets_counts_each_transition_once() -> None:
    from test_rl_interop import KW as RKW  # same folder (pytest's default import mode)
    from test_rl_interop import SEED, _actions, _hand_run

    steps, S = 20, 2
    acts = _actions(steps, S)
    env = RecordEpisodeStatistics(SwarmVectorEnv(n_scenes=S, autoreset="disabled", **RKW))
    env.reset(seed=SEED)
    got: list[list[tuple[float, int]]] = [[] for _ in range(2 * S)]
    done = np.zeros(2 * S, dtype=bool)
    for k in range(steps):
        if done.any():
            env.reset(options={"reset_mask": done})
        _, _, te, tr, infos = env.step(acts[k].reshape(2 * S, 3).astype(np.float32))
        done = te | tr
        for i in np.flatnonzero(infos.get("_episode", np.zeros(2 * S, dtype=bool))):
            got[i].append((float(infos["episode"]["r"][i]), int(infos["episode"]["l"][i])))
    for s in range(S):
        eps = _hand_run(s, acts[:, s], next_step=False)
        for j in range(2):
            assert len(eps) >= 2
            np.testing.assert_allclose([g[0] for g in got[2 * s + j]],
                                       [float(e["r"][j]) for e in eps], rtol=1e-12)
            assert [g[1] for g in got[2 * s + j]] == [e["l"] for e in eps]


def test_vector_env_takes_gymnasium_seed_lists_per_sub_env() -> None:
    a = SwarmVectorEnv(n_scenes=2, **KW)
    b = SwarmVectorEnv(n_scenes=2, **KW)
    a.reset(seed=[3, 3, 8, 8])
    b.reset(seed=[3, 8])
    assert a.vec.batch.roots == b.vec.batch.roots == [3, 8]
    with pytest.raises(ValueError, match=r"^seed: the 2 agents of scene 0 share it"):
        a.reset(seed=[3, 4, 8, 8])


def test_render_mode_ansi_and_state_space() -> None:
    with pytest.raises(ValueError, match=r"^render_mode: must be None or one of \['ansi'\], "
                       r"got 'human'$"):
        SwarmEnv(scenario={"nodes": 3}, render_mode="human")
    env = SwarmEnv(scenario={"nodes": 3}, max_steps=3, render_mode="ansi")
    assert env.metadata["render_modes"] == ["ansi"] and env.render_mode == "ansi"
    env.reset(seed=1)
    _, _, _, _, info = env.step({a: np.zeros(3, dtype=np.float32) for a in env.agents})
    text = env.render()
    lines = text.splitlines()
    truth = env.state()
    assert lines[0] == f"scene 0 episode 0 t={env.vec.batch.scenes[0].now():.3f} s"
    assert len(lines) == 2 + 3
    cells = lines[3].split()  # node_1, an agent: its age and error are shown
    assert cells[0] == "node_1"
    assert float(cells[1]) == round(truth[1, 9], 2) and float(cells[2]) == round(truth[1, 10], 2)
    own = info["node_1"]
    assert cells[6] == f"{own['aoi']:.3f}" and cells[7] == f"{own['error']:.2f}"
    assert lines[2].split()[6:] == ["-", "-"]  # the scripted leader has neither
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert SwarmEnv(scenario={"nodes": 3}).render() is None
    # state_space: PettingZoo's parallel state test, and the space's exact form
    assert env.state_space.shape == (3, 12) and env.state_space.dtype == np.float64
    assert env.state_space.contains(truth)
    state_parallel_test(SwarmEnv(scenario={"nodes": 3}))
    vec = SwarmVectorEnv(n_scenes=2, render_mode="ansi", **KW)
    vec.reset(seed=0)
    out = vec.render()
    assert isinstance(out, tuple) and [o.splitlines()[0][:17] for o in out] == [
        "scene 0 episode 0", "scene 1 episode 0"]
    assert vec.vec.state().shape == (2, 3, 12)
