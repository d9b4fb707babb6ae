"""``sigma-des tune`` refuses bad files and oversize runs before any work (issue 26):
exit 2 and one line naming the option."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigma_des.cli import main
from sigma_des.tuning.cli import tune_bytes
from sigma_des.tuning.flightlog import read_csv, write_csv
from sigma_des.tuning.spec import TuneSpec
from sigma_des.tuning.synth import fly

TINY = ["--set", "tune.population=4", "--set", "tune.generations=1"]


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("logs")
    return write_csv(fly("quadrotor", "quadrotor", duration=3.0, seed=1), d / "tune.csv")


def _err(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["tune", "--dynamics", "quadrotor", *TINY, *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300).map(lambda b: b"t,\xff" + b))
def test_binary_log(tmp_path: Path, capsys: pytest.CaptureFixture[str], data: bytes) -> None:
    f = tmp_path / "bin.csv"
    f.write_bytes(data)
    err = _err(["--log", str(f), "--out", str(tmp_path / "o")], capsys)
    assert f"--log {f}: not a UTF-8 text CSV flight log (undecodable byte at offset 2)" in err


def test_latin1_validation_log_and_init(log: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    latin = tmp_path / "latin.csv"
    latin.write_bytes(log.read_bytes().replace(b"t,", "t\u00e9,".encode("latin-1"), 1))
    err = _err(["--log", str(log), "--validate", str(latin), "--out", str(tmp_path / "o")],
               capsys)
    assert f"--validate {latin}: not a UTF-8 text CSV flight log" in err
    err = _err(["--log", str(log), "--init", str(latin), "--out", str(tmp_path / "o")], capsys)
    assert f"--init {latin}: not a UTF-8 text fitted parameter file" in err
    err = _err(["--log", str(log), "--init", str(tmp_path), "--out", str(tmp_path / "o")],
               capsys)
    assert f"--init {tmp_path}: is a directory, not a fitted parameter file" in err
    err = _err(["--log", str(tmp_path), "--out", str(tmp_path / "o")], capsys)
    assert f"--log {tmp_path}: is a directory, not a CSV flight log" in err


def test_config_directory_or_binary(log: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["--log", str(log), "--config", str(tmp_path), "--out", str(tmp_path / "o")],
               capsys)
    assert f"--config: {tmp_path}: is a directory, not a tune config file" in err
    b = tmp_path / "c.toml"
    b.write_bytes(b"[tune]\npopulation = \xff\n")
    err = _err(["--log", str(log), "--config", str(b), "--out", str(tmp_path / "o")], capsys)
    assert "--config: " in err and "not a UTF-8 text tune config file" in err


@pytest.mark.parametrize("where", ["file", "under-file", "proc"])
def test_out_unwritable_before_the_work(log: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str], where: str) -> None:
    f = tmp_path / "f.txt"
    f.write_text("x")
    out, want = {
        "file": (f, "is an existing file, not a directory"),
        "under-file": (f / "o", f"lies under {f}, which is a file"),
        "proc": (Path("/proc/sigma_des_tune"), "cannot write to directory /proc/sigma_des_tune"),
    }[where]
    err = _err(["--log", str(log), "--out", str(out)], capsys)
    assert err.startswith("sigma-des: error: --out: ") and want in err
    assert "R²" not in capsys.readouterr().out  # the GA did not run


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_out_read_only(log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        err = _err(["--log", str(log), "--out", str(ro / "o")], capsys)
        assert "--out: cannot write" in err
    finally:
        ro.chmod(0o700)


def test_population_memory_check(log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    spec = TuneSpec(population=10_000)
    # 3 windows of 51 samples, 28 states + 12 observations, float64, 1.5x reserve
    assert tune_bytes(read_csv(log, "quadrotor"), spec) == int(1.5 * 10_000 * 3 * 51 * 40 * 8)
    import sigma_des.budget as budget

    monkeypatch.setattr(budget, "available_bytes", lambda: 2**29)
    err = _err(["--log", str(log), "--set", "tune.population=10000", "--out",
                str(tmp_path / "o")], capsys)
    assert "memory: tune.population=10000 needs about 0.684 GiB, but 0.5 GiB is available" in err
    assert "lower tune.population" in err and "--force" in err
    assert not (tmp_path / "o").exists()


def test_a_population_beyond_the_maximum_is_refused(log: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    # the old documented maximum: a batched flight of gigabytes that ran for minutes
    err = _err(["--log", str(log), "--set", "tune.population=100000", "--set",
                "tune.generations=1", "--out", str(tmp_path / "o")], capsys)
    assert "tune.population: must be in 2..10000, got 100000" in err
    assert not (tmp_path / "o").exists()
