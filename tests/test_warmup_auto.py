"""``warmup = -1`` (default): 0.1 x duration, so every allowed duration validates (issue 22.6)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sigma_des import ConfigError, load
from sigma_des.cli import main
from sigma_des.config import MAX_DURATION_S, WARMUP_FRACTION, config_hash, to_toml
from sigma_des.sweep.grid import apply_point


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=1e-6, max_value=MAX_DURATION_S, allow_nan=False))
def test_every_allowed_duration_validates_with_the_default_warmup(duration: float) -> None:
    sc = load(None, [f"duration={duration!r}"])
    assert sc.warmup == WARMUP_FRACTION * duration
    assert 0 <= sc.warmup < sc.duration


@pytest.mark.parametrize("duration", [0.5, 1.0, 0.001])
def test_short_durations_from_the_command_line(duration: float,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """``--set duration=1`` (or less) failed with the fixed 1 s warm-up."""
    assert main(["config", "--set", f"duration={duration}"]) == 0
    assert f"(here {0.1 * duration:g} s)" in capsys.readouterr().out


def test_the_default_run_is_unchanged() -> None:
    """10 s with 1 s of warm-up, as before: the same hash as the explicit value."""
    sc = load(None)
    assert sc.warmup == 1.0
    assert config_hash(sc) == config_hash(load(None, ["warmup=1.0"]))


def test_an_explicit_warmup_is_still_checked_and_kept() -> None:
    with pytest.raises(ConfigError) as ei:
        load(None, ["duration=1", "warmup=1"])
    assert ei.value.key == "warmup" and "-1 (auto" in ei.value.reason
    with pytest.raises(ConfigError):
        load(None, ["warmup=-0.5"])
    sc = load(None, ["warmup=0.3", "duration=2"])
    assert sc.warmup == 0.3 and "\nwarmup = 0.3\n" in to_toml(sc)


def test_automatic_warmup_follows_duration_in_files_and_sweeps(tmp_path: Path) -> None:
    auto = load(None)
    assert "\nwarmup = -1.0\n" in to_toml(auto)
    f = tmp_path / "a.toml"
    f.write_text(to_toml(auto).replace("\nduration = 10.0\n", "\nduration = 0.5\n"))
    assert load(f).warmup == 0.05
    assert apply_point(auto, {"duration": 0.5}).warmup == 0.05
    fixed = load(None, ["warmup=0.2"])
    assert apply_point(fixed, {"duration": 0.5}).warmup == 0.2
