"""Scenario validation, TOML round trip and the CLI's handling of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sigma_des import ConfigError, Scenario, load, to_toml
from sigma_des.cli import main
from sigma_des.config import config_hash


@pytest.mark.parametrize(
    ("override", "key", "words"),
    [
        ("nodse=5", "nodse", "unknown key"),
        ("net.host_link.latncy=0.1", "net.host_link.latncy", "unknown key"),
        ("nodes='many'", "nodes", "integer"),
        ("nodes=0", "nodes", "1..1000000"),
        ("net.host_link.latency.value=-0.001", "net.host_link.latency.value", ">= 0"),
        ("net.host_link.latency=-0.001", "net.host_link.latency.value", ">= 0"),
        ("net.host_link.loss.p=1.0", "net.host_link.loss.p", "1"),
        ("net.qos=2", "net.qos", "0 or 1"),
        ("net.transport='tcp'", "net.transport", "datagram"),
        ("bides.rate_down=1.5", "bides.rate_down", "(0, 1)"),
        ("methods=['none','fast']", "methods", "unknown method"),
        ("warmup=20", "warmup", "duration"),
        ("hosts=500", "hosts", "nodes"),
        ("faults=[{kind='crash', node=999}]", "faults[0].node", "0..199"),
        ("faults=[{kind='melt', node=1}]", "faults[0].kind", "crash"),
        ("dynamics='rocket'", "dynamics", "pointmass"),
    ],
)
def test_bad_values_name_the_key(override: str, key: str, words: str) -> None:
    with pytest.raises(ConfigError) as ei:
        load(None, [override])
    assert ei.value.key == key
    assert words in ei.value.reason


@pytest.mark.parametrize(
    "override",
    ["nodse=5", "nodes=0", "net.host_link.latency.value=-1", "net.host_link.loss.p=1.0",
     "nodes=1.5"],
)
def test_cli_exits_2_naming_the_key(override: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", "--set", override, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert override.split("=")[0] in err
    assert "error" in err


def test_cli_rejects_unknown_method(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", "--methods", "none,warp"]) == 2
    assert "--methods" in capsys.readouterr().err


def test_cli_missing_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "/nonexistent/x.toml"]) == 2
    assert "not found" in capsys.readouterr().err


def test_config_round_trips_through_toml(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    sc = load(None, ["nodes=17", "net.host_link.latency={dist='uniform', low=0.001, high=0.002}",
                     "faults=[{kind='slow', node=3, factor=5.0, start=1.0}]"])
    p = tmp_path / "s.toml"
    p.write_text(to_toml(sc))
    assert load(p) == sc
    assert main(["config", str(p)]) == 0
    assert "nodes = 17" in capsys.readouterr().out


def test_defaults_round_trip() -> None:
    import tomllib

    assert load(None) == Scenario()
    assert tomllib.loads(to_toml(Scenario()))["nodes"] == 200


def test_config_hash_ignores_seed_methods_and_engine_only() -> None:
    a = Scenario()
    assert config_hash(a) == config_hash(Scenario(seed=9, methods=("bides",)))
    assert config_hash(a) == config_hash(Scenario(engine="events"))  # same results
    assert config_hash(a) != config_hash(Scenario(nodes=201))


def test_unknown_engine_names_the_choices() -> None:
    with pytest.raises(ConfigError, match="engine: must be one of \\('cohort', 'events'\\)"):
        Scenario(engine="fast")


def test_cli_compare_writes_table_and_files(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    args = ["compare", "--set", "nodes=6", "--set", "hosts=2", "--set", "duration=0.6",
            "--set", "warmup=0.1", "--out", str(tmp_path / "a"), "--no-progress"]
    assert main(args) == 0
    out = capsys.readouterr().out
    for m in ("none", "lockstep", "hlc", "bides"):
        assert m in out
    s1 = json.loads((tmp_path / "a" / "summary.json").read_text())
    args[-2] = str(tmp_path / "b")
    assert main(args) == 0
    s2 = json.loads((tmp_path / "b" / "summary.json").read_text())
    s1.pop("wall")
    s2.pop("wall")
    assert s1 == s2
    header = (tmp_path / "a" / "results.csv").read_text().splitlines()[0]
    assert header == "seed,config_hash,version,method,metric,value,unit"
    # every method ran on the default cohort engine, and both the file and the footer say so
    assert {m: e["used"] for m, e in s1["engines"].items()} == dict.fromkeys(
        ("none", "lockstep", "hlc", "bides"), "cohort")
    assert "engine cohort: none, lockstep, hlc, bides" in out


def test_cli_footer_names_a_fallback_and_its_reason(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["compare", "--set", "nodes=4", "--set", "hosts=1", "--set", "duration=0.3",
            "--set", "warmup=0.1", "--set", 'net.middleware="dds"', "--set",
            'net.transport="datagram"', "--set", "net.qos=0", "--methods", "none",
            "--no-progress"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "engine events: none" in out
    assert "none fell back to the per-message engine: DDS middleware" in out
