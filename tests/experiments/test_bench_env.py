"""experiments/bench_env.py: smoke run at tiny scale (no timing asserted)."""

from __future__ import annotations

import json
import sys
from importlib.util import find_spec
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import bench_env  # noqa: E402

from sigma_des.config import METHODS  # noqa: E402


def test_quick_run_writes_every_case(tmp_path: Path) -> None:
    assert bench_env.main(["--quick", "--variant", "default", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "bench.json").read_text())
    cases = {(r["method"], r["scenes"]) for r in data["rows"]}
    assert cases == {(m, s) for m in METHODS for s in (1, 2)}
    assert all(r["agent_steps_per_s"] > 0 for r in data["rows"])
    # a scene holds at least its history rings: 64 frames x 11 nodes x 12 float64
    assert all(b > 64 * 11 * 12 * 8 for b in data["memory_bytes_per_scene"].values())
    assert (tmp_path / "bench.csv").read_text().count("\n") == len(data["rows"]) + 1

def test_study_mode_measures_the_delay_study_configuration(tmp_path: Path) -> None:
    assert bench_env.main(["--study", "--quick", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "bench_study.json").read_text())
    cases = {(r["condition"], r["scenes"]) for r in data["rows"]}
    assert cases == {(c, s) for c in ("bides@200ms", "perfect") for s in (1, 2)}
    assert all(r["agent_steps_per_s"] > 0 for r in data["rows"])
    assert all(r["metrics"] is False for r in data["rows"])  # the study's env arguments
    # the steady figure counts the episodes' restarts: at most one per scene-step
    assert all(0 <= r["restarts_per_scene_step"] <= 1 for r in data["rows"])
    assert all(r["within_episode_agent_steps_per_s"] > 0 for r in data["rows"])
    assert data["episode_steps"] == 50 and data["warm_steps"] == 60
    assert data["fit_scenes"] == 4 and data["rss_bytes_per_scene"] == (
        data["rss_grown_bytes"] / 4)
    if find_spec("stable_baselines3") is None:  # the `learn` extra: no PPO timing
        assert "ppo" not in data
    else:  # one scene x 4 agents x rollouts of 8 steps: 64 agent-steps are 2 rollouts
        p = data["ppo"]
        assert p["agent_steps"] == 64 and p["scenes"] == 1
        assert p["minutes_per_policy"] == pytest.approx(2e6 / 64 * p["wall_s"] / 60)
        assert p["wall_s"] > 0 and p["env_cpu_s"] > 0


def test_a_negative_ppo_budget_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        bench_env.main(["--study", "--ppo", "-1"])
    assert exc.value.code == 2
    assert "--ppo: must be >= 0 (0: no PPO timing), got -1" in capsys.readouterr().err


@pytest.mark.parametrize("option", ["--steady", "--steps", "--reps", "--fit"])
def test_a_count_below_one_is_refused_naming_the_option(
        option: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        bench_env.main(["--study", option, "0"])
    assert exc.value.code == 2
    assert f"{option}: must be >= 1, got 0" in capsys.readouterr().err
