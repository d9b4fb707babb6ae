"""Two `compare --record SAME.mcap` (or `--out SAME_DIR`) at once: the second is refused
naming the option while the first writes; part names are unique to a run, and a killed
run's parts are removed by the next run of the same recording."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sigma_des.cli import LOCK_NAME, main
from sigma_des.lock import OutputLock
from sigma_des.record import open_recording
from sigma_des.record.parts import RecordParts

FAST = ["--set", "dynamics=pointmass", "--set", "fidelity.enabled=false"]
SMALL = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2", *FAST,
         "--methods", "none,bides", "--no-progress", "--no-plots"]


def test_part_names_are_unique_to_a_run_and_stale_parts_go(tmp_path: Path) -> None:
    out = tmp_path / "x.mcap"
    stale = tmp_path / ".x.mcap.999-abcdef.none.part"
    stale.write_bytes(b"a killed run's part")
    other = tmp_path / ".y.mcap.999-abcdef.none.part"  # another recording's: kept
    other.write_bytes(b"")
    parts = RecordParts(out, ["none", "bides"])
    try:
        assert not stale.exists() and other.exists()
        names = {m: parts.get(m).name for m in ("none", "bides")}
        run = names["none"].split(".")[3]
        assert run.startswith(f"{os.getpid()}-")
        assert names == {"none": f".x.mcap.{run}.none.part",
                         "bides": f".x.mcap.{run}.bides.part"}
        assert (tmp_path / ".x.mcap.lock").exists()
    finally:
        parts.remove()
    assert sorted(p.name for p in tmp_path.iterdir()) == [other.name]  # lock released


def test_a_second_recording_to_the_same_file_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.mcap"
    with OutputLock(tmp_path / ".x.mcap.lock", "--record", str(out)):  # another run's
        assert main(["compare", *SMALL, "--record", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (f"sigma-des: error: --record: {out} is being written by another run "
                   f"(process {os.getpid()}); wait for it to end, or write elsewhere\n")
    assert os.listdir(tmp_path) == []  # no part, no recording


def test_a_second_run_into_the_same_out_folder_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "o"
    out.mkdir()
    with OutputLock(out / LOCK_NAME, "--out", str(out)):
        assert main(["compare", *SMALL, "--out", str(out)]) == 2
    assert "error: --out: " + str(out) + " is being written by another run" in (
        capsys.readouterr().err)
    assert os.listdir(out) == []
    assert main(["compare", *SMALL, "--out", str(out)]) == 0  # free again: runs, no lock left
    assert sorted(os.listdir(out)) == ["results.csv", "summary.json", "wall.csv"]


def test_two_real_runs_at_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The first run (a process) records; the second, started meanwhile, is refused and
    the first's recording is whole."""
    long = ["--set", "nodes=6", "--set", "duration=4", "--set", "warmup=1", *FAST,
            "--methods", "none,bides", "--no-progress", "--no-plots"]
    p = subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "compare", *long, "--record",
                          "x.mcap", "--out", "o"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 300
    while not list(tmp_path.glob(".x.mcap.*.part")):
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < end
        time.sleep(0.05)
    assert main(["compare", *SMALL, "--record", str(tmp_path / "x.mcap")]) == 2
    assert main(["compare", *SMALL, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert [e.split(": ")[1:3] for e in err] == [["error", "--record"], ["error", "--out"]]
    assert all(f"(process {p.pid})" in e for e in err)
    _out, perr = p.communicate(timeout=600)
    assert p.returncode == 0, perr
    assert open_recording(tmp_path / "x.mcap").methods == ["none", "bides"]
    assert sorted(os.listdir(tmp_path)) == ["o", "x.mcap"]
