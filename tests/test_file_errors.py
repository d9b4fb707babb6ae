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


# ---------------------------------------------------------------- issue 26

SMALL = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2", "--set",
         "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
         "--methods", "none,bides"]


def test_compare_out_where_the_tables_fit_but_the_plots_do_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 40 KiB disk: the tables (a few KiB) are written whole, the first PNG fails; one
    line naming --out and the PNG, no partial PNG, no temporary file."""
    pytest.importorskip("matplotlib")
    import pandas as pd
    from tmpfs import tmpfs

    with tmpfs(tmp_path / "tiny", size="40k") as tiny:
        out = tiny / "o"
        assert main(["compare", *SMALL, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err and err.count("\n") == 1, err
        assert err.startswith(f"sigma-des: error: --out: cannot write {out}/")
        assert err.rstrip().endswith(".png: No space left on device")
        assert sorted(os.listdir(out)) == ["results.csv", "summary.json", "wall.csv"]
        assert set(pd.read_csv(out / "results.csv")["method"]) == {"none", "bides"}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "r.mcap"
    assert main(["compare", *SMALL, "--record", str(path)]) == 0
    return path


@pytest.mark.parametrize("command", ["replay", "tune"])
def test_force_overrides_the_memory_estimate(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch, command: str,
) -> None:
    """1 KiB available: refused naming ``memory`` and --force; with --force it runs."""
    import sigma_des.budget as budget

    monkeypatch.setattr(budget, "available_bytes", lambda: 1024)
    if command == "replay":
        argv = ["replay", str(recording), "--rate", "10", "--out", str(tmp_path / "t.csv")]
        made = tmp_path / "t.csv"
    else:
        from sigma_des.tuning.flightlog import write_csv
        from sigma_des.tuning.synth import fly

        log = write_csv(fly("quadrotor", "quadrotor", duration=3.0, seed=1), tmp_path / "l.csv")
        argv = ["tune", "--dynamics", "quadrotor", "--log", str(log), "--set",
                "tune.population=4", "--set", "tune.generations=1", "--out", str(tmp_path / "o")]
        made = tmp_path / "o" / "fitted.toml"
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("sigma-des: error: memory: ") and err.count("\n") == 1
    assert "but 9.54e-07 GiB is available" in err and err.rstrip().endswith("or pass --force")
    assert not made.exists()
    assert main([*argv, "--force"]) == 0
    assert made.stat().st_size > 0


def _fixtures(recording: Path, d: Path) -> dict[str, Path]:
    """A flight log and a live-run directory for tune and calibrate."""
    from sigma_des.tuning.flightlog import write_csv
    from sigma_des.tuning.synth import fly

    log = write_csv(fly("quadrotor", "quadrotor", duration=3.0, seed=1), d / "l.csv")
    from tests.calibrate.test_calibrate_inputs import SETS, _run, _write

    sc = load(None, SETS)
    return {"log": log, "live": _write(d / "live", sc, _run(sc)), "rec": recording}


def _argv(command: str, fx: dict[str, Path], out: Path) -> list[str]:
    return {
        "replay": ["replay", str(fx["rec"]), "--rate", "2000", "--out", str(out / "t.csv")],
        "calibrate": ["calibrate", str(fx["live"]), "--no-check", "--out", str(out / "c.toml")],
        "tune": ["tune", "--dynamics", "quadrotor", "--log", str(fx["log"]), "--set",
                 "tune.population=4", "--set", "tune.generations=1", "--out", str(out / "o")],
        "compare --out": ["compare", *SMALL, "--no-plots", "--out", str(out / "o")],
        "compare --record": ["compare", *SMALL, "--record", str(out / "x.mcap")],
    }[command]


COMMANDS = ["replay", "calibrate", "tune", "compare --out", "compare --record"]


@pytest.mark.parametrize("command", COMMANDS)
def test_an_output_on_a_read_only_file_system(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """Root writes into chmod-0555 folders; a read-only mount stops everyone: one line
    naming the option, before any work."""
    from tmpfs import tmpfs

    fx = _fixtures(recording, tmp_path)
    with tmpfs(tmp_path / "ro", read_only=True) as ro:
        assert main(_argv(command, fx, ro)) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    key = "--record" if command == "compare --record" else "--out"
    assert err.startswith(f"sigma-des: error: {key}: cannot write")
    assert err.rstrip().endswith(": Read-only file system")


@pytest.mark.parametrize("command", COMMANDS)
def test_a_full_disk_on_a_real_tmpfs(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """8 KiB: one line naming the option and ENOSPC; no hidden temporary file is left
    and nothing truncated under a final name."""
    from tmpfs import tmpfs

    fx = _fixtures(recording, tmp_path)
    with tmpfs(tmp_path / "tiny", size="8k") as tiny:
        assert main(_argv(command, fx, tiny)) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err and err.count("\n") == 1, err
        key = "--record" if command == "compare --record" else "--out"
        assert err.startswith(f"sigma-des: error: {key}: cannot write")
        assert err.rstrip().endswith(": No space left on device")
        left = [p for p in tiny.rglob("*") if p.is_file()]
    assert not [p for p in left if p.name.startswith(".")], left
    # every command's files are one set, all or none (calibrate's sample files too)
    assert left == [], left
