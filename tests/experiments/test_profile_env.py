"""experiments/profile_env.py: smoke run at tiny scale (structure only; no timing asserted)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import profile_env  # noqa: E402


def test_quick_profile_ranks_the_env_and_the_message_core(
        capsys: pytest.CaptureFixture[str]) -> None:
    res = profile_env.profile("bides@200ms", 2, 2, 1, False, 400)
    out = capsys.readouterr().out
    assert "bides@200ms, 2 scenes, metrics False:" in out
    assert res["agent_steps_per_s"] > 0 and res["us_per_scene_step"] > 0
    shares = res["files"]
    assert abs(sum(shares.values()) - 1.0) < 1e-9
    assert {"sigma_des/env/vector.py", "sigma_des/events/fast/loop.py",
            "sigma_des/events/engine.py"} <= set(shares)
    assert "sigma_des/metrics/collector.py" not in shares or shares[
        "sigma_des/metrics/collector.py"] < 0.05  # the null collector: next to nothing


@pytest.mark.parametrize("bad", [["--scenes", "0"], ["--steps", "-1"], ["--warm", "-2"]])
def test_bad_sizes_exit_2(bad: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        profile_env.main(bad)
    assert e.value.code == 2 and bad[0] in capsys.readouterr().err
