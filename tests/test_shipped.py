"""Shipped scenarios: package data, runnable by name from any directory (issue 22.10)."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigma_des import ConfigError, load
from sigma_des.cli import main
from sigma_des.shipped import DIR, names, resolve

CHECKOUT = Path(__file__).resolve().parents[1]


def test_the_shipped_files_are_the_checkout_s_scenarios() -> None:
    assert names() == ["airsim_rpc", "gazebo_lockstep_dds", "latency_tolerance"]
    assert (CHECKOUT / "scenarios").resolve() == DIR


def test_names_resolve_outside_the_checkout(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    for n in names():
        assert load(n) == load(DIR / f"{n}.toml") == load(f"{n}.toml")
    assert load("airsim_rpc").methods == ("rpc",)


def test_a_local_file_wins_over_a_shipped_name(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "latency_tolerance.toml").write_text("nodes = 7\n")
    assert load("latency_tolerance.toml").nodes == 7
    assert resolve("latency_tolerance") == DIR / "latency_tolerance.toml"  # no such file here
    assert resolve("sub/latency_tolerance") == Path("sub/latency_tolerance")  # a path: as is


def test_an_unknown_name_lists_the_shipped_ones(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as ei:
        load("latency_tolerence")
    assert ei.value.key == "latency_tolerence"
    assert "airsim_rpc, gazebo_lockstep_dds, latency_tolerance" in ei.value.reason
    assert main(["config", "latency_tolerence"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
