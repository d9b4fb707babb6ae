"""RL libraries on the vector env: Gymnasium's RecordEpisodeStatistics, SB3 PPO, SuperSuit.

Every recorded number is checked against a hand-run: the same actions replayed in
one single-scene, non-autoresetting :class:`SwarmVec` per scene (scenes are isolated,
so scene ``s`` of the batch plays exactly the episodes of a lone scene with id ``s``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from gymnasium.wrappers.vector import RecordEpisodeStatistics

from sigma_des.env import SwarmVec, SwarmVectorEnv

# 3 nodes = 2 agents per scene; div 0.2 (3 m): random actions end some episodes by
# divergence before max_steps, others are truncated
KW: dict[str, Any] = {"scenario": {"nodes": 3}, "max_steps": 6, "task_params": {"div": 0.2}}
SEED = 3


def _actions(steps: int, n_scenes: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform(-0.6, 0.6, (steps, n_scenes, 2, 3)).astype(np.float32)


def _hand_run(scene: int, acts: np.ndarray, next_step: bool) -> list[dict[str, Any]]:
    """Episodes of scene ``scene`` for its actions ``acts[k]`` (k = vector step)."""
    env = SwarmVec(n_scenes=1, scene_ids=[scene], autoreset="disabled", **KW)
    obs, _ = env.reset(seed=SEED)
    episodes: list[dict[str, Any]] = []
    ret, length, first = np.zeros(2), 0, obs[0]
    for k in range(len(acts)):
        if env.done[0]:
            obs, _ = env.reset()
            ret, length, first = np.zeros(2), 0, obs[0]
            if next_step:  # the vector env spends this step on the reset
                continue
        obs, r, te, tr, _ = env.step(acts[k][None])
        ret += r[0]
        length += 1
        if te[0, 0] or tr[0, 0]:
            episodes.append({"r": ret.copy(), "l": length, "term": bool(te[0, 0]),
                             "final": obs[0], "first": first, "end": k})
    return episodes


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_record_episode_statistics_matches_a_hand_run(mode: str) -> None:
    steps, S = 20, 2
    acts = _actions(steps, S)
    env = RecordEpisodeStatistics(SwarmVectorEnv(n_scenes=S, autoreset=mode, **KW))
    _, infos = env.reset(seed=SEED)
    assert "episode" not in infos and infos["episode_index"].tolist() == [0, 0, 0, 0]
    got: list[list[tuple[float, int]]] = [[] for _ in range(2 * S)]
    for k in range(steps):
        _, _, _, _, infos = env.step(acts[k].reshape(2 * S, 3).astype(np.float32))
        for i in np.flatnonzero(infos.get("_episode", np.zeros(2 * S, dtype=bool))):
            got[i].append((float(infos["episode"]["r"][i]), int(infos["episode"]["l"][i])))
    kinds = set()
    for s in range(S):
        eps = _hand_run(s, acts[:, s], next_step=mode == "next_step")
        kinds |= {e["term"] for e in eps}
        for j in range(2):
            want = [(float(e["r"][j]), e["l"]) for e in eps]
            assert len(want) >= 2
            np.testing.assert_allclose([g[0] for g in got[2 * s + j]], [w[0] for w in want],
                                       rtol=1e-12)
            assert [g[1] for g in got[2 * s + j]] == [w[1] for w in want]
    assert kinds == {True, False}  # both terminated and truncated episodes were counted


def test_same_step_reports_the_final_observation_and_returns_the_next_episode() -> None:
    steps, S = 14, 2
    acts = _actions(steps, S)
    env = SwarmVec(n_scenes=S, autoreset="same_step", **KW)
    env.reset(seed=SEED)
    ends = {s: {e["end"]: e for e in _hand_run(s, acts[:, s], next_step=False)}
            for s in range(S)}
    seen = 0
    for k in range(steps):
        obs, _, te, tr, infos = env.step(acts[k])
        for s in range(S):
            done = bool(te[s, 0] or tr[s, 0])
            mask = infos.get("_final_obs", np.zeros((S, 2), dtype=bool))  # only on an end
            assert mask[s].tolist() == [done, done]
            if not done:
                continue
            seen += 1
            ep = ends[s][k]
            np.testing.assert_array_equal(infos["final_obs"][s], ep["final"])
            assert infos["final_info"]["episode_index"][s] == infos["episode_index"][s] - 1
            assert np.isnan(infos["error"][s]).all() and np.isfinite(
                infos["final_info"]["error"][s]).all()
            later = [e for e in ends[s].values() if e["end"] > k]
            if later:  # the returned observation is the next episode's first
                np.testing.assert_array_equal(obs[s], later[0]["first"])
    assert seen >= 4


def test_bad_autoreset_mode_is_named() -> None:
    with pytest.raises(ValueError, match="autoreset: unknown mode 'later'"):
        SwarmVec(autoreset="later")


# ---------------------------------------------------------------- Stable-Baselines3
def test_sb3_adapter_marks_truncation_and_termination() -> None:
    pytest.importorskip("stable_baselines3")
    from sigma_des.env.sb3 import SwarmSB3VecEnv

    steps, S = 14, 2
    acts = _actions(steps, S)
    env = SwarmSB3VecEnv(n_scenes=S, **KW)
    env.seed(SEED)
    env.reset()
    ends = {s: {e["end"]: e for e in _hand_run(s, acts[:, s], next_step=False)}
            for s in range(S)}
    flags = set()
    for k in range(steps):
        _, rew, dones, infos = env.step(acts[k].reshape(2 * S, 3).astype(np.float32))
        assert rew.dtype == np.float32 and dones.shape == (2 * S,)
        for i in np.flatnonzero(dones):
            s, j = divmod(int(i), 2)
            ep = ends[s][k]
            np.testing.assert_array_equal(infos[i]["terminal_observation"], ep["final"][j])
            assert infos[i]["TimeLimit.truncated"] == (not ep["term"])
            flags.add(infos[i]["TimeLimit.truncated"])
        for i in np.flatnonzero(~dones):
            assert "terminal_observation" not in infos[i]
    assert flags == {True, False}
    with pytest.raises(ValueError, match="autoreset: SB3 needs 'same_step'"):
        SwarmSB3VecEnv(autoreset="next_step")


def test_sb3_ppo_learns_through_the_adapter_and_vecmonitor_counts_true_episodes() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnvWrapper, VecMonitor

    from sigma_des.env.sb3 import SwarmSB3VecEnv

    class Taped(VecEnvWrapper):  # type: ignore[misc]
        """Keeps the actions PPO sends, to replay them by hand."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.tape: list[np.ndarray] = []

        def reset(self) -> Any:
            return self.venv.reset()

        def step_async(self, actions: np.ndarray) -> None:
            self.tape.append(np.array(actions, dtype=np.float32))
            self.venv.step_async(actions)

        def step_wait(self) -> Any:
            return self.venv.step_wait()

    S = 2
    kw = {"scenario": {"nodes": 3}, "max_steps": 10}
    taped = Taped(SwarmSB3VecEnv(n_scenes=S, **kw))
    env = VecMonitor(taped)
    model = PPO("MlpPolicy", env, n_steps=40, batch_size=40, n_epochs=2, seed=SEED,
                device="cpu")
    model.learn(total_timesteps=300)
    assert model.num_timesteps == 320  # 2 rollouts of 40 steps x 4 sub-envs (2 scenes x 2)
    assert all(np.isfinite(p.detach().numpy()).all() for p in model.policy.parameters())
    # replay the taped actions scene by scene: SB3's episode records are the true ones
    acts = np.stack(taped.tape).reshape(-1, S, 2, 3)
    want = []
    for s in range(S):
        vec = SwarmVec(n_scenes=1, scene_ids=[s], autoreset="disabled", **kw)
        vec.reset(seed=model.seed)  # PPO seeds the env with its own seed
        ret, length = np.zeros(2), 0
        for k in range(len(acts)):
            if vec.done[0]:
                vec.reset()
                ret, length = np.zeros(2), 0
            _, r, te, tr, _ = vec.step(acts[k, s][None])
            ret, length = ret + r[0], length + 1
            if te[0, 0] or tr[0, 0]:
                want += [(k, 2 * s + j, float(ret[j]), length) for j in range(2)]
    got = sorted((float(e["r"]), int(e["l"])) for e in model.ep_info_buffer)
    ref = sorted((np.float32(r).item(), n) for _, _, r, n in want)
    assert len(got) == len(ref) == 8 * 4  # 80 steps / 10 per episode, x 4 sub-envs
    np.testing.assert_allclose([g[0] for g in got], [r[0] for r in ref], rtol=1e-6)
    assert {g[1] for g in got} == {10}  # no reset step counted as a transition


def test_supersuit_sb3_path_over_the_pettingzoo_env_runs_ppo() -> None:
    pytest.importorskip("stable_baselines3")
    ss = pytest.importorskip("supersuit")
    from stable_baselines3 import PPO

    from sigma_des.env import SwarmEnv

    venv = ss.pettingzoo_env_to_vec_env_v1(SwarmEnv(scenario={"nodes": 3}, max_steps=10))
    venv = ss.concat_vec_envs_v1(venv, 2, num_cpus=0, base_class="stable_baselines3")
    assert venv.num_envs == 4
    # no seed=: SuperSuit 3.11's ConcatVecEnv has no seed() for SB3 2.9 (AttributeError)
    model = PPO("MlpPolicy", venv, n_steps=20, batch_size=40, n_epochs=1, device="cpu")
    model.learn(total_timesteps=80)
    assert model.num_timesteps == 80
    # what our adapter adds: SuperSuit never marks a max_steps end as a time limit
    venv.reset()
    for _ in range(10):
        _, _, dones, infos = venv.step(np.zeros((4, 3), dtype=np.float32))
    assert dones.all() and not any(i.get("TimeLimit.truncated", False) for i in infos)
