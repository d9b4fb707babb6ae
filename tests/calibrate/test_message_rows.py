"""Malformed rows of messages.csv.gz: counted, reported and dropped, or the table refused
above 1 %; a damaged gzip stream is refused naming the file (no zlib traceback)."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from sigma_des.calibrate.fit import calibrate
from sigma_des.calibrate.messages import read_messages
from sigma_des.cli import main
from sigma_des.config import to_toml
from sigma_des.errors import ConfigError
from tests.calibrate.test_calibrate_bad_inputs import _good

M = "messages.csv.gz"


def _lines(run: Path) -> list[str]:
    return gzip.decompress((run / M).read_bytes()).decode().splitlines(keepends=True)


def _put(run: Path, lines: list[str]) -> None:
    (run / M).write_bytes(gzip.compress("".join(lines).encode()))


def test_a_lost_comma_drops_the_row_and_says_so(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    run, clean = _good(tmp_path / "run"), _good(tmp_path / "clean")
    lines = _lines(run)
    n = len(lines) - 1
    i = next(j for j, s in enumerate(lines) if s.startswith("bides,state,"))
    _put(clean, lines[:i] + lines[i + 1:])  # the same table without that row
    lines[i] = "bidesstate," + lines[i][len("bides,state,"):]  # `bides,state` lost its comma
    _put(run, lines)
    df = read_messages(run)
    assert (len(df), df.attrs["malformed"]) == (n - 1, 1)
    assert (f"{run / M}: 1 of {n} rows are malformed (first: line {i + 1}, unknown method "
            "bidesstate); dropped them") in capsys.readouterr().err
    assert df.equals(read_messages(clean))
    # the fit is that of the table without the row, and the CLI reports the drop
    a, b = calibrate(run, tmp_path / "a"), calibrate(clean, tmp_path / "b")
    assert to_toml(a[0]).replace(str(tmp_path / "a"), "F") == to_toml(b[0]).replace(
        str(tmp_path / "b"), "F")
    assert {p.name: p.read_bytes() for p in (tmp_path / "a").iterdir()} == {
        p.name: p.read_bytes() for p in (tmp_path / "b").iterdir()}
    assert main(["calibrate", str(run), "--out", str(tmp_path / "c.toml"), "--no-check"]) == 0
    assert "1 of" in capsys.readouterr().err


@pytest.mark.parametrize(("edit", "why"), [
    (lambda s: s.replace(",state,", ",stat,", 1), "unknown kind stat"),
    (lambda s: s.replace(",", ",x", 5).replace(",x", ",", 4), "is not a finite number"),
    (lambda s: ",".join(s.split(",")[:6]) + ",,,,False\n", "without t_recv"),
])
def test_more_than_one_percent_is_refused(edit, why: str, tmp_path: Path,  # type: ignore[no-untyped-def]
                                          capsys: pytest.CaptureFixture[str]) -> None:
    run = _good(tmp_path / "run")
    lines = _lines(run)
    states = [j for j, s in enumerate(lines) if ",state," in s]
    n_bad = (len(lines) - 1) // 100 + 1  # just above 1 %
    for j in states[:n_bad]:
        lines[j] = edit(lines[j])
    _put(run, lines)
    with pytest.raises(ConfigError, match=f"{n_bad} of {len(lines) - 1} rows are malformed "
                                          rf"\(first: line {states[0] + 1}, .*{why}"):
        read_messages(run)
    assert main(["calibrate", str(run), "--out", str(tmp_path / "c.toml"), "--no-check"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sigma-des: error: {run / M}: ") and "more than 1%" in err
    assert not (tmp_path / "c.toml").exists()


def test_a_flipped_gzip_flag_bit_is_refused_naming_the_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = _good(tmp_path / "run")
    data = bytearray((run / M).read_bytes())
    data[3] ^= 0x02  # FHCRC: the deflate stream is read 2 bytes late (a zlib.error)
    (run / M).write_bytes(bytes(data))
    assert main(["calibrate", str(run), "--out", str(tmp_path / "c.toml"), "--no-check"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sigma-des: error: {run / M}: not readable as a gzip-compressed CSV")
    assert "Traceback" not in err and len(err.splitlines()) == 1
