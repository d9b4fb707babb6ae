"""`calibrate` on bad inputs (issue 26): a broken message table or summary.json and an
unwritable ``--out`` each end in exit 2 and one line naming the file or option, with no
traceback and nothing written; the outputs are written all or nothing."""

from __future__ import annotations

import gzip
import json
import os
from pathlib import Path

import numpy as np
import pytest

from sigma_des import load
from sigma_des.calibrate.fit import calibrate
from sigma_des.cli import main
from sigma_des.errors import ConfigError
from tests.calibrate.test_calibrate_inputs import SETS, _run, _write


def _good(d: Path) -> Path:
    sc = load(None, SETS)
    return _write(d, sc, _run(sc))


def _files(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    return err


M, S = "messages.csv.gz", "summary.json"
BROKEN = {  # the file, its content, the error
    "random bytes": (M, np.random.default_rng(5).bytes(4096),
                     r"messages\.csv\.gz: not readable as a gzip-compressed CSV"),
    "0 bytes": (M, b"", r"messages\.csv\.gz: is empty; expected a gzip-compressed CSV"),
    "empty gzip": (M, gzip.compress(b""), r"messages\.csv\.gz: is empty; expected"),
    "header only": (M, gzip.compress(b"method,kind,host,node,frame,t_send,t_recv\n"),
                    r"messages\.csv\.gz: has a header but no message rows"),
    "summary garbage": (S, b"\x00\xff garbage {",
                        r"summary\.json: not a UTF-8 text summary\.json"),
    "summary not JSON": (S, b"{scenario: 1",
                         r"summary\.json: not valid JSON \(Expecting property name"),
    "summary without scenario": (S, json.dumps({"methods": {}}).encode(),
                                 r"summary\.json: has no 'scenario' table"),
    "summary a list": (S, b"[1, 2]", r"summary\.json: has no 'scenario' table"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_input_file_is_refused(case: str, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    run = _good(tmp_path / "run")
    name, data, pattern = BROKEN[case]
    (run / name).write_bytes(data)
    before = _files(tmp_path)
    out = tmp_path / "cal" / "c.toml"
    err = _refused(["calibrate", str(run), "--out", str(out), "--no-check"], capsys)
    assert err.startswith(f"sigma-des: error: {run / name}: ")
    with pytest.raises(ConfigError, match=pattern):
        calibrate(run, tmp_path / "f")
    assert _files(tmp_path) == before  # no scenario, report or sample file


def test_an_unwritable_out_is_refused_before_the_fit(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    run = _good(tmp_path / "run")
    before = _files(tmp_path)
    (tmp_path / "adir").mkdir()
    err = _refused(["calibrate", str(run), "--out", str(tmp_path / "adir"), "--no-check"],
                   capsys)
    assert f"--out: {tmp_path / 'adir'} is a directory; give a file path" in err
    err = _refused(["calibrate", str(run), "--out", "/proc/cal.toml", "--no-check"], capsys)
    assert "sigma-des: error: --out: cannot write /proc/cal.toml" in err
    assert _files(tmp_path) == before  # not even the sample files next to the source


@pytest.mark.parametrize("nth", [2, 3, 4])  # hop_down.txt, the scenario, its report
def test_a_failed_write_leaves_nothing_under_the_final_names(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch, nth: int) -> None:
    """The sample files, the scenario and its report are one set: whichever file the
    disk fills up on, none of them is left (no complete-looking half calibration)."""
    run = _good(tmp_path / "run")
    out = tmp_path / "cal" / "c.toml"
    real = os.fsync
    calls = {"n": 0}

    def full(fd: int) -> None:  # the disk fills up on the nth file's fsync
        calls["n"] += 1
        if calls["n"] == nth:
            raise OSError(28, "No space left on device")
        real(fd)

    monkeypatch.setattr(os, "fsync", full)
    err = _refused(["calibrate", str(run), "--out", str(out), "--no-check"], capsys)
    assert "--out: cannot write" in err and "No space left on device" in err
    assert not (tmp_path / "cal").exists()  # no part file, nor the folder made for --out
    monkeypatch.setattr(os, "fsync", real)
    assert main(["calibrate", str(run), "--out", str(out), "--no-check"]) == 0
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == [
        "c.json", "c.toml", "hop_down.txt", "hop_up.txt"]
    assert load(str(out)).nodes == 4
