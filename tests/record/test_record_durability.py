"""``compare --record`` on bad paths, full disks and signals (issue 26).

An unwritable recording is refused before any run (exit 2, one line naming
``--record``); a write that fails during the runs or the join (disk full) is one line
too, and leaves nothing behind, not even the hidden part files; Ctrl-C keeps the
methods that finished (table, ``--out``, recording) and SIGKILL during the join never
leaves a truncated file under the recording's name.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from procs import wait_gone
from tmpfs import tmpfs

import sigma_des.api
from sigma_des import ConfigError, compare, load
from sigma_des.cli import main
from sigma_des.record import open_recording, read_table

SMALL = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2", "--set",
         "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
         "--methods", "none,bides"]
#: long enough that a signal sent once the second method has started lands in it
LONG = ["--set", "nodes=20", "--set", "duration=30", "--set", "warmup=1", "--set",
        "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
        "--methods", "none,bides"]
NO_SPACE = "No space left on device"


def _one_line(rc: int, err: str, want_rc: int = 2) -> str:
    assert rc == want_rc, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err.strip()


def _never_run(*args: object, **kw: object) -> None:
    raise AssertionError("the runs started before the recording was checked")


@pytest.mark.parametrize("jobs", ["1", "2"])
@pytest.mark.parametrize("where", ["proc", "read-only"])
def test_an_unwritable_recording_is_refused_before_the_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    where: str, jobs: str,
) -> None:
    monkeypatch.setattr(sigma_des.api, "_run_methods", _never_run)
    if where == "proc":
        out, why = Path("/proc/x.mcap"), "No such file or directory"
        rc = main(["compare", *SMALL, "--jobs", jobs, "--record", str(out)])
    else:
        with tmpfs(tmp_path / "ro", read_only=True) as ro:
            out, why = ro / "x.mcap", "Read-only file system"
            rc = main(["compare", *SMALL, "--jobs", jobs, "--record", str(out)])
    err = _one_line(rc, capsys.readouterr().err)
    assert err == f"sigma-des: error: --record: cannot write {out}: {why}"


def test_the_api_checks_the_recording_before_the_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sigma_des.api, "_run_methods", _never_run)
    with pytest.raises(ConfigError) as ei:
        compare(load(None, ["nodes=3"]), ["none"], progress=False, record="/proc/x.mcap")
    assert ei.value.key == "--record" and "cannot write /proc/x.mcap" in ei.value.reason


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_full_disk_during_the_runs_is_one_line_and_leaves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], jobs: str
) -> None:
    with tmpfs(tmp_path / "tiny", size="64k") as tiny:
        rc = main(["compare", *SMALL, "--jobs", jobs, "--record", str(tiny / "x.mcap")])
        err = _one_line(rc, capsys.readouterr().err)
        assert err == f"sigma-des: error: --record: cannot write {tiny / 'x.mcap'}: {NO_SPACE}"
        assert os.listdir(tiny) == []


def _no_space(*args: object, **kw: object) -> None:
    raise OSError(errno.ENOSPC, NO_SPACE)


@pytest.mark.parametrize("stage", ["runs", "join"])
def test_a_failed_write_keeps_the_previous_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    stage: str,
) -> None:
    """The write raising ENOSPC (a full disk anywhere): one line, the old file intact."""
    import sigma_des.record.writer as writer

    if stage == "runs":
        monkeypatch.setattr(writer.Writer, "add_message", _no_space)
    else:
        monkeypatch.setattr(writer.Recorder, "copy_from", _no_space)
    out = tmp_path / "x.mcap"
    out.write_bytes(b"the previous recording")
    rc = main(["compare", *SMALL, "--record", str(out)])
    err = _one_line(rc, capsys.readouterr().err)
    assert err == f"sigma-des: error: --record: cannot write {out}: {NO_SPACE}"
    assert out.read_bytes() == b"the previous recording"
    assert os.listdir(tmp_path) == ["x.mcap"]


#: compare with Recorder.copy_from SIGKILLing the process at the second part: the join
#: is under way (its output file open, the first part registered)
_KILLED_IN_JOIN = """
import os, signal, sys
from sigma_des.record import writer
calls = []
copy = writer.Recorder.copy_from
def dying(self, part):
    calls.append(part)
    if len(calls) == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    copy(self, part)
writer.Recorder.copy_from = dying
from sigma_des.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_sigkill_during_the_join_leaves_the_previous_recording(tmp_path: Path) -> None:
    out = tmp_path / "x.mcap"
    out.write_bytes(b"the previous recording")
    p = subprocess.run([sys.executable, "-c", _KILLED_IN_JOIN, "compare", *SMALL,
                        "--record", str(out)], capture_output=True, text=True, timeout=600)
    assert p.returncode == -signal.SIGKILL, p.stderr
    assert out.read_bytes() == b"the previous recording"
    # what SIGKILL leaves is hidden (the next run of the same recording replaces it)
    assert all(f.startswith(".x.mcap.") for f in os.listdir(tmp_path) if f != "x.mcap")


def _start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "compare", *argv], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_for(path: Path, p: subprocess.Popen[str], limit: float = 300.0) -> None:
    end = time.monotonic() + limit
    while not any(path.parent.glob(path.name)):  # a pattern: the part names hold the run
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < end, f"{path} never appeared"
        time.sleep(0.05)


def test_ctrl_c_after_a_method_finished_keeps_it(tmp_path: Path) -> None:
    """The terminal's Ctrl-C (SIGINT to the process group) while ``bides`` runs: the
    finished ``none`` is printed, written to --out and recorded; exit 130."""
    p = _start([*LONG, "--record", "x.mcap", "--out", "o"], tmp_path)
    _wait_for(tmp_path / ".x.mcap.*.bides.part", p)  # none finished, bides is running
    time.sleep(0.5)
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=300)
    assert p.returncode == 130, err
    assert err == "sigma-des: interrupted; kept the 1 finished method(s): none\n"
    assert " none " in out and "bides" not in out
    assert set(pd.read_csv(tmp_path / "o" / "results.csv")["method"]) == {"none"}
    assert open_recording(tmp_path / "x.mcap").methods == ["none"]
    assert set(read_table(tmp_path / "x.mcap")["method"]) == {"none"}
    assert sorted(os.listdir(tmp_path)) == ["o", "x.mcap"]


def test_ctrl_c_before_any_method_finished_leaves_nothing(tmp_path: Path) -> None:
    """``--jobs 2``: both methods running in workers, Ctrl-C to the process group."""
    p = _start([*LONG, "--jobs", "2", "--record", "x.mcap", "--out", "o"], tmp_path)
    for m in ("none", "bides"):
        _wait_for(tmp_path / f".x.mcap.*.{m}.part", p)
    os.killpg(p.pid, signal.SIGINT)
    _out, err = p.communicate(timeout=300)
    assert p.returncode == 130 and err == "sigma-des: interrupted\n", err
    assert os.listdir(tmp_path) == []  # not even the --out folder made for the run


def _children(pid: int) -> list[int]:
    ps = subprocess.run(["ps", "-eo", "pid=,ppid="], capture_output=True, text=True,
                        timeout=30).stdout.split()
    return [int(c) for c, pp in zip(ps[::2], ps[1::2], strict=True) if int(pp) == pid]


def test_sigkill_of_compare_takes_its_workers_along(tmp_path: Path) -> None:
    p = _start([*LONG, "--jobs", "2", "--record", "x.mcap"], tmp_path)
    for m in ("none", "bides"):
        _wait_for(tmp_path / f".x.mcap.*.{m}.part", p)
    workers = _children(p.pid)
    assert len(workers) >= 2
    p.kill()
    p.wait(timeout=60)  # not communicate(): living workers would hold its pipes open
    for fh in (p.stdout, p.stderr):
        if fh is not None:
            fh.close()
    assert wait_gone(workers), workers


def test_a_run_that_fails_leaves_no_part_file(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """Any error (here the recorder's close raising) removes the parts and propagates."""
    import sigma_des.record.writer as writer

    def broken(self: object) -> None:
        raise RuntimeError("broken recorder")

    monkeypatch.setattr(writer.Recorder, "close", broken)
    sc = load(None, ["nodes=3", "duration=1.0", "warmup=0.2", "dynamics='pointmass'",
                     "fidelity.enabled=false"])
    with pytest.raises(RuntimeError, match="broken recorder"):
        compare(sc, ["none"], progress=False, record=tmp_path / "x.mcap")
    assert os.listdir(tmp_path) == []
