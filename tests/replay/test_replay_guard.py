"""``sigma-des replay`` refuses bad input before any work (issue 26): exit 2, one line
naming the option; the CSV is written all or nothing."""

from __future__ import annotations

import os
import resource
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigma_des.cli import main
from sigma_des.replay.cli import MAX_RATE, MAX_WINDOW_W, replay_bytes

SMALL = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2", "--set",
         "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
         "--methods", "none,bides"]


@pytest.fixture(scope="module")
def rec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "r.mcap"
    assert main(["compare", *SMALL, "--record", str(path)]) == 0
    return path


def _err(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["replay", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize(("rate", "shown"), [
    ("1e12", "got 1000000000000.0"), ("1e308", "got 1e+308"), ("nan", "got nan"),
    ("0", "got 0.0"), ("-5", "got -5.0"), ("inf", "got inf"),
])
def test_rate_out_of_bounds(rec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                            rate: str, shown: str) -> None:
    err = _err([str(rec), "--rate", rate, "--out", str(tmp_path / "t.csv")], capsys)
    assert f"--rate: must be in (0, {MAX_RATE:g}] Hz, {shown}" in err
    assert not (tmp_path / "t.csv").exists()


def test_window_w_bound(rec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for w in ("1000000000", "-1"):
        err = _err([str(rec), "--rate", "10", "--window", "both", "--window-w", w,
                    "--out", str(tmp_path / "t.csv")], capsys)
        assert f"--window-w: must be in 0..{MAX_WINDOW_W} samples, got {w}" in err


def test_recording_that_is_a_directory_or_missing(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    err = _err([str(tmp_path), "--rate", "10", "--out", str(tmp_path / "t.csv")], capsys)
    assert f"recording: {tmp_path}: is a directory" in err
    err = _err([str(tmp_path / "no.mcap"), "--rate", "10", "--out", str(tmp_path / "t.csv")],
               capsys)
    assert "recording (MCAP file) not found" in err and "no.mcap" in err


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_recording_of_random_bytes(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   data: bytes) -> None:
    f = tmp_path / "junk.mcap"
    f.write_bytes(data)
    err = _err([str(f), "--rate", "10", "--out", str(tmp_path / "t.csv"), "--force"], capsys)
    assert str(f) in err


def test_truncated_recording(rec: Path, tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(rec.read_bytes()[: rec.stat().st_size // 2])
    err = _err([str(cut), "--rate", "10", "--out", str(tmp_path / "t.csv")], capsys)
    assert "truncated" in err


@pytest.mark.parametrize("where", ["dir", "dir-force", "proc", "under-file"])
def test_out_unwritable_is_refused_before_the_work(
    rec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str
) -> None:
    a_file = tmp_path / "f.txt"
    a_file.write_text("x")
    out, extra, want = {
        "dir": (tmp_path, [], "is a directory; give a file path"),
        "dir-force": (tmp_path, ["--force"], "is a directory; give a file path"),
        "proc": (Path("/proc/sigma_des_t.csv"), [], "cannot write /proc/sigma_des_t.csv"),
        "under-file": (a_file / "t.csv", [], f"lies under {a_file}, which is a file"),
    }[where]
    err = _err([str(rec), "--rate", "10", "--out", str(out), *extra], capsys)
    assert err.startswith("sigma-des: error: --out: ") and want in err
    assert "replayed" not in capsys.readouterr().out


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_out_in_read_only_folder(rec: Path, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        err = _err([str(rec), "--rate", "10", "--out", str(ro / "t.csv")], capsys)
        assert "--out: cannot write" in err and "Permission denied" in err
    finally:
        ro.chmod(0o700)


def test_memory_estimate_refuses_huge_output(rec: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # 3 nodes x 1 s x 2 methods at 1e6 Hz: 6e6 rows x 288 B = 1.7 GB
    assert replay_bytes({"nodes": 3, "duration": 1.0}, 2, 1e6) == int(2 * 3 * (1e6 + 1) * 288)
    import sigma_des.budget as budget

    monkeypatch.setattr(budget, "available_bytes", lambda: 2**30)
    err = _err([str(rec), "--rate", "1e6", "--out", str(tmp_path / "t.csv")], capsys)
    assert "memory: replay at --rate 1e+06 Hz needs about 1.61 GiB" in err
    assert "1 GiB is available; lower --rate or pick --methods, or pass --force" in err


def test_write_failure_leaves_nothing_under_the_final_name(rec: Path, tmp_path: Path) -> None:
    """A file-size limit makes the CSV write fail part-way (EFBIG, like a full disk)."""
    out = tmp_path / "t.csv"

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    p = subprocess.run([sys.executable, "-m", "sigma_des.cli", "replay", str(rec), "--rate",
                        "2000", "--out", str(out)], capture_output=True, text=True,
                       preexec_fn=limit, timeout=300)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith(f"sigma-des: error: --out: cannot write {out}: File too large")
    assert "Traceback" not in p.stderr and p.stderr.count("\n") == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_csv_mode_follows_the_umask(rec: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.csv"
    old = os.umask(0o027)
    try:
        assert main(["replay", str(rec), "--rate", "10", "--out", str(out)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o640
    assert out.read_text().startswith("method,node,t,")
