"""Every file error is exit 2 with a message naming the file (issue 9.6)."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigma_des import ConfigError, load
from sigma_des.cli import main
from sigma_des.sweep.store import ResultStore

FIXTURE = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
#: bytes that are not UTF-8 text (a lone continuation byte or an invalid lead byte)
BINARY = st.binary(min_size=0, max_size=200).map(lambda b: b + b"\xff\xfe\x80" + b)


@FIXTURE
@given(BINARY)
def test_binary_scenario_file(tmp_path: Path, data: bytes) -> None:
    f = tmp_path / "s.toml"
    f.write_bytes(data)
    with pytest.raises(ConfigError) as ei:
        load(f)
    assert ei.value.key == str(f) and "UTF-8" in ei.value.reason


def test_scenario_directory_and_unreadable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["config", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    f = tmp_path / "s.toml"
    f.write_text("nodes = 4\n")
    f.chmod(0)
    try:
        if os.geteuid() != 0:
            assert main(["config", str(f)]) == 2
            err = capsys.readouterr().err
            assert str(f) in err and "cannot read" in err
    finally:
        f.chmod(0o600)


@FIXTURE
@given(BINARY)
def test_binary_empirical_file(tmp_path: Path, data: bytes) -> None:
    f = tmp_path / "lat.txt"
    f.write_bytes(data)
    with pytest.raises(ConfigError) as ei:
        load(None, [f'net.host_link.latency={{dist="empirical", file="{f}"}}'])
    assert ei.value.key.endswith("file")
    assert "not a text file" in ei.value.reason or "not a number" in ei.value.reason


def test_empirical_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["config", "--set", f'net.host_link.latency={{dist="empirical", file="{tmp_path}"}}'])
    assert rc == 2
    err = capsys.readouterr().err
    assert "net.host_link.latency.file" in err and "is a directory" in err


@FIXTURE
@given(st.binary(min_size=1, max_size=5000))
def test_store_that_is_not_a_database(tmp_path: Path, data: bytes) -> None:
    f = tmp_path / "s.sqlite"
    f.write_bytes(data)
    with pytest.raises(ConfigError) as ei:
        ResultStore(f).close()
    assert ei.value.key == "--store" and "not a sigma-des results store" in ei.value.reason


@FIXTURE
@given(st.floats(0.05, 0.95))
def test_truncated_store(tmp_path: Path, keep: float) -> None:
    f = tmp_path / "t.sqlite"
    f.unlink(missing_ok=True)
    with ResultStore(f) as s:
        for i in range(200):
            s.put_config(f"h{i:04d}", {"pad": "x" * 200})
    db = sqlite3.connect(f)
    db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    db.close()
    data = f.read_bytes()
    f.write_bytes(data[: max(1, int(len(data) * keep))])
    for side in (f.with_name(f.name + "-wal"), f.with_name(f.name + "-shm")):
        side.unlink(missing_ok=True)
    with pytest.raises(ConfigError) as ei:
        ResultStore(f).close()
    assert ei.value.key == "--store"


def test_store_directory_and_empty_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sets = ["--set", "hosts=1", "--set", "duration=0.3", "--set", "warmup=0.1"]
    argv = ["sweep", *sets, "--grid", "nodes=3", "--in-process", "--dry-run"]
    assert main([*argv, "--store", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    empty = tmp_path / "e.sqlite"
    empty.write_bytes(b"")
    assert main([*argv, "--store", str(empty)]) == 2
    assert "is an empty file" in capsys.readouterr().err
    assert empty.stat().st_size == 0  # left untouched
