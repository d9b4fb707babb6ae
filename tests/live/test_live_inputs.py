"""``live`` refuses, before anything starts, what would fail after the run or swamp
the machine: an unwritable ``--record``, too many host processes, too much memory."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

from sigma_des.cli import main
from sigma_des.config import load
from sigma_des.errors import ConfigError
from sigma_des.live import runner
from sigma_des.live.limits import HOSTS_PER_CORE, check_size
from sigma_des.live.runner import LiveOptions, run_live


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("path", ["/proc/live.mcap", "/proc/self/live.mcap"])
def test_record_where_nothing_can_be_written_fails_before_the_run(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    def no_run(*a: Any, **k: Any) -> None:
        raise AssertionError("the run started")

    monkeypatch.setattr(runner, "run_live", no_run)
    err = _one_line_error(capsys, ["live", "--set", "nodes=4", "--record", path])
    assert err.startswith(f"sigma-des: error: --record: cannot write {path}: ")


def test_record_probe_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def stop(*a: Any, **k: Any) -> None:
        raise ConfigError("probe", "stop here")

    monkeypatch.setattr(runner, "run_live", stop)
    assert main(["live", "--set", "nodes=4", "--record", str(tmp_path / "x.mcap")]) == 2
    assert os.listdir(tmp_path) == []  # writable: accepted, and the probe file removed


def test_too_many_host_processes_are_refused_naming_hosts(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    def no_broker(*a: Any, **k: Any) -> None:
        raise AssertionError("the broker started")

    monkeypatch.setattr(runner, "Broker", no_broker)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    err = _one_line_error(capsys, ["live", "--set", "nodes=100000"])  # 5000 hosts (20 each)
    assert err.startswith("sigma-des: error: hosts: 5000 host processes (nodes=100000)")
    assert f"at most {2 * HOSTS_PER_CORE}" in err and "--force" in err
    sc = load(None, ["nodes=170", "hosts=17"])
    with pytest.raises(ConfigError, match="^hosts: 17 host processes"):
        run_live(sc, ["none"])
    check_size(load(None, ["nodes=160", "hosts=16"]))  # 16 = 8 per core: accepted
    check_size(load(None, []))  # the default scenario (200 nodes, 10 hosts) runs


def test_memory_estimate_refuses_naming_the_keys(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("sigma_des.budget.available_bytes", lambda: 2**30)  # 1 GiB free
    err = _one_line_error(capsys, ["live", "--set", "nodes=4", "--set", "hosts=2",
                                   "--set", "duration=3000"])
    # 2 hosts x 200 MiB + 256 MiB; rows: 3000 s x (100 Hz x (2 x 4 states + 3 triggers)
    # + 20 Hz x 4 commands) x 300 B = 967 MiB; compare's arrays 99.6 MiB: 1.727 GiB
    assert ("error: memory: a live run of nodes=4 on hosts=2 over duration=3000 s needs "
            "about 1.73 GiB") in err and "lower nodes, hosts or duration, or pass --force" in err
    assert "1 GiB is available" in err
    small = load(None, ["nodes=4", "hosts=2", "duration=1.5"])
    assert check_size(small) < 2**30  # the test scenarios fit
    big = load(None, ["nodes=4", "hosts=2", "duration=3000"])
    assert check_size(big, force=True) > 2**30  # --force: estimated, not refused
    assert LiveOptions(force=True).force
