"""The PPO recipes (``sigma_des.env.ppo``): frame stacking, normalisation, resume, LSTM.

Tiny budgets: these check the plumbing (what the policy sees, what a resumed run
keeps), not that PPO learns (that is the delay study's job, see docs/ENV.md).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from sigma_des.env.learn import score  # noqa: E402
from sigma_des.env.ppo import LSTM_HIDDEN, Acting, train  # noqa: E402

KW: dict[str, Any] = {"task": "tight", "scenario": {"nodes": 3}, "max_steps": 5,
                      "perfect_info": True, "method": "none"}
TINY = {"n_steps": 8, "batch_size": 16, "n_epochs": 1}


class _Echo:
    """A model whose action is the first three columns of what it is shown."""

    def predict(self, x: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return x[:, :3].copy(), None


class _Half:
    """A normaliser that halves the observations."""

    def normalize_obs(self, x: np.ndarray) -> np.ndarray:
        return x / 2


def test_stacked_policy_sees_the_last_frames_oldest_first_and_reset_clears_them() -> None:
    act = Acting(_Echo(), _Half(), "stack", n_stack=3)
    o = [np.full((1, 2, 4), float(k + 1), dtype=np.float32) for k in range(4)]
    # stacked row = [f_{t-2}, f_{t-1}, f_t] of 4 columns each; the model echoes columns 0-2
    assert act(o[0]).tolist() == [[[0.0, 0.0, 0.0]] * 2]
    act(o[1])
    assert act(o[2]).tolist() == [[[0.5, 0.5, 0.5]] * 2]  # frame 1 (halved) is the oldest
    assert act(o[3]).tolist() == [[[1.0, 1.0, 1.0]] * 2]
    act.reset()
    assert act(o[3]).tolist() == [[[0.0, 0.0, 0.0]] * 2]
    mlp = Acting(_Echo(), _Half(), "mlp", n_stack=3)
    assert mlp(o[3]).tolist() == [[[2.0, 2.0, 2.0]] * 2]


def test_training_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    ck = tmp_path / "ck" / "perfect_mlp_s0"
    rows: list[dict[str, float]] = []
    _, h1 = train(KW, 32, 0, n_scenes=2, checkpoint=ck, log=rows.append, **TINY)
    # 2 scenes x 2 agents = 4 sub-envs, 8 steps a rollout: 32 agent-steps per rollout
    assert [r["agent_steps"] for r in h1] == [32.0] and rows == h1
    assert ck.with_suffix(".zip").exists() and ck.with_suffix(".norm.pkl").exists()
    assert json.loads(ck.with_suffix(".curve.json").read_text()) == h1
    policy, h2 = train(KW, 96, 0, n_scenes=2, checkpoint=ck, **TINY)
    assert [r["agent_steps"] for r in h2] == [32.0, 64.0, 96.0] and h2[0] == h1[0]
    assert policy.model.num_timesteps == 96 and policy.norm.training is False
    # a finished training is only loaded; max_wall_s=0 also only loads
    _, h3 = train(KW, 96, 0, n_scenes=2, checkpoint=ck, **TINY)
    _, h4 = train(KW, 500, 0, n_scenes=2, checkpoint=ck, max_wall_s=0, **TINY)
    assert h3 == h2 == h4
    res = score(policy, KW, episodes=2, seed=5)
    assert res["fitness"].shape == (2,) and np.isfinite(res["fitness"]).all()


def test_wall_budget_stops_between_rollouts(tmp_path: Path) -> None:
    ck = tmp_path / "p"
    _, h = train(KW, 10_000, 0, n_scenes=2, checkpoint=ck, max_wall_s=1e-9, **TINY)
    assert [r["agent_steps"] for r in h] == [32.0]  # one rollout, then the budget stops it
    assert json.loads(ck.with_suffix(".curve.json").read_text()) == h


def test_recurrent_policy_trains_and_keeps_its_state_per_episode() -> None:
    pytest.importorskip("sb3_contrib")
    policy, h = train(KW, 32, 0, policy="lstm", n_scenes=2, **TINY)
    assert [r["agent_steps"] for r in h] == [32.0]
    assert policy.model.policy.lstm_actor.hidden_size == LSTM_HIDDEN == 64
    obs = np.zeros((2, 2, policy.model.observation_space.shape[0]), dtype=np.float32)
    first = policy(obs)
    second = policy(obs)  # same input, carried state: generally a different action
    policy.reset()
    assert np.array_equal(policy(obs), first)
    assert first.shape == (2, 2, 3) and np.abs(second).max() <= 1.0


def test_unknown_policy_is_named() -> None:
    with pytest.raises(ValueError, match=r"^policy: must be one of \('mlp', 'stack', 'lstm'\), "
                       "got 'cnn'$"):
        train(KW, 32, 0, policy="cnn")


def test_study_with_ppo_resumes_finished_trainings(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))
    import train_under_delay

    args = ["--learner", "ppo", "--policy", "stack", "--delays", "none", "--seeds", "1",
            "--nodes", "3", "--max-steps", "5", "--eval-episodes", "2", "--ppo-steps", "32",
            "--ppo-scenes", "2", "--ppo-n-steps", "8", "--ppo-batch", "16",
            "--out", str(tmp_path)]
    assert train_under_delay.main(args) == 0
    first = (tmp_path / "eval.csv").read_text()
    data = json.loads((tmp_path / "summary.json").read_text())
    names = {r["policy"] for r in data["perfect"]}
    assert names == {"untrained", "naive", "extrapolating", "trained perfect"}
    assert (tmp_path / "checkpoints" / "perfect_stack_s0.done.json").exists()
    capsys.readouterr()
    assert train_under_delay.main(args) == 0
    assert "seed 0 perfect        done before" in capsys.readouterr().out
    # the same evaluations (their wall-time column aside): nothing was retrained
    assert _evals(tmp_path / "eval.csv") == _evals_text(first)


def _evals_text(text: str) -> list[dict[str, str]]:
    import csv
    import io

    return [{k: v for k, v in r.items() if k != "eval_wall_s"}
            for r in csv.DictReader(io.StringIO(text))]


def _evals(path: Path) -> list[dict[str, str]]:
    return _evals_text(path.read_text())


def test_training_leaves_no_logger_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                          ) -> None:
    # SB3's default logger would make this folder (or /tmp/SB3-<time>) per training
    from sigma_des.env.sb3 import train_ppo

    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3"))
    _, h = train(KW, 16, 0, n_scenes=2, **TINY)
    _, h2 = train_ppo(KW, 16, 0, n_scenes=2, **TINY)
    assert h and h2
    assert not (tmp_path / "sb3").exists()
