"""``sigma-des replay``: exact at the recorded instants; every bad input exits 2."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sigma_des.cli import main
from sigma_des.record import Recorder, read_states
from sigma_des.replay import INTERP_METHODS
from sigma_des.replay.replay import replay


def _record(path: Path, frames: int = 40, mode: str = "full",
            t_of: object = None) -> None:
    with Recorder(path, scenario={}, mode=mode) as rec:
        for method in ("none", "bides"):
            run = rec.run(method)
            for k in range(frames):
                for i in range(2):
                    t = k / 100 if t_of is None else t_of(k)  # type: ignore[operator]
                    run.state(node=i, frame=k, t_send=t, t_recv=t + 0.003,
                              pos=(10 * math.sin(k / 7) + i, 3.0 * k / 100, -50.0 - i),
                              vel=(10 / 7 * 100 * math.cos(k / 7) / 100, 3.0, 0.0),
                              att=(0.0, 0.05, k / 50))
            if method == "bides":  # a duplicate delivery of frame 5 must not matter
                run.state(node=0, frame=5, t_send=0.05, t_recv=0.09,
                          pos=(10 * math.sin(5 / 7), 0.15, -50.0), vel=(0, 3, 0),
                          att=(0, 0.05, 0.1))


@pytest.mark.parametrize("method", INTERP_METHODS)
def test_replay_reproduces_the_recording_at_the_recorded_instants(tmp_path: Path,
                                                                  method: str) -> None:
    path = tmp_path / "r.mcap"
    _record(path)
    df = replay(path, 100.0, method)
    st = read_states(path, "none")["none"]
    for node in (0, 1):
        got = df[(df.method == "none") & (df.node == node)]
        want = st.node == node
        np.testing.assert_array_equal(got.t.to_numpy(), st.t_send[want])
        np.testing.assert_array_equal(got[["x", "y", "z"]].to_numpy(), st.pos[want])
        np.testing.assert_array_equal(got[["phi", "theta", "psi"]].to_numpy(), st.att[want])
    assert len(df[(df.method == "bides") & (df.node == 0)]) == 40  # duplicate dropped


def test_cli_writes_the_csv_and_upsamples(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _record(path)
    out = tmp_path / "traj.csv"
    assert main(["replay", str(path), "--rate", "250", "--method", "pchip",
                 "--methods", "bides", "--out", str(out)]) == 0
    dw = tmp_path / "dw.csv"
    assert main(["replay", str(path), "--rate", "250", "--window", "both", "--window-w", "2",
                 "--methods", "bides", "--out", str(dw)]) == 0
    assert len(pd.read_csv(dw)) == 2 * 98
    assert main(["replay", str(path), "--rate", "250", "--window-w", "-1",
                 "--out", str(tmp_path / "x.csv")]) == 2
    df = pd.read_csv(out)
    assert set(df.method) == {"bides"} and set(df.node) == {0, 1}
    assert len(df) == 2 * 98  # 0 .. 0.39 s at 250 Hz: k = 0 .. 97
    assert list(df.columns) == ["method", "node", "t", "x", "y", "z", "phi", "theta", "psi"]


def _bad_cases(tmp_path: Path) -> dict[str, tuple[list[str], str]]:
    good = tmp_path / "good.mcap"
    _record(good)
    short = tmp_path / "short.mcap"
    _record(short, frames=3)
    back = tmp_path / "back.mcap"
    _record(back, t_of=lambda k: (k if k != 20 else 18.5) / 100)
    trunc = tmp_path / "trunc.mcap"
    trunc.write_bytes(good.read_bytes()[:-500])
    corrupt = tmp_path / "corrupt.mcap"
    b = bytearray(good.read_bytes())
    for j in range(300, 400):
        b[j] ^= 0x5A
    corrupt.write_bytes(bytes(b))
    out = str(tmp_path / "o.csv")
    return {
        "truncated": ([str(trunc), "--rate", "60", "--out", out], "truncated"),
        "corrupt": ([str(corrupt), "--rate", "60", "--out", out], "corrupt"),
        "missing": ([str(tmp_path / "nope.mcap"), "--rate", "60", "--out", out], "not found"),
        "rate0": ([str(good), "--rate", "0", "--out", out], "--rate: must be"),
        "rate-": ([str(good), "--rate", "-5", "--out", out], "--rate: must be"),
        "few": ([str(short), "--rate", "60", "--method", "akima", "--out", out],
                "3 recorded states, method akima needs at least 5"),
        "order": ([str(back), "--rate", "60", "--out", out], "timestamps not increasing"),
        "method": ([str(good), "--rate", "60", "--methods", "hlc", "--out", out],
                   "'hlc' is not in"),
    }


@pytest.mark.parametrize("case", ["truncated", "corrupt", "missing", "rate0", "rate-", "few",
                                  "order", "method"])
def test_bad_input_exits_2_naming_file_and_problem(tmp_path: Path, case: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    argv, needle = _bad_cases(tmp_path)[case]
    assert main(["replay", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    if case in ("truncated", "corrupt", "missing", "few", "order"):
        assert argv[0] in err  # names the file
    assert not (tmp_path / "o.csv").exists()


def test_non_finite_state_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "nan.mcap"
    with Recorder(path) as rec:
        run = rec.run("none")
        for k in range(6):
            run.state(node=0, frame=k, t_send=k / 10, t_recv=k / 10,
                      pos=(math.nan if k == 3 else 0.0, 0, 0), vel=(0, 0, 0), att=(0, 0, 0))
    assert main(["replay", str(path), "--rate", "60", "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "none node 0: times and samples must be finite" in err


def test_unknown_schema_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mcap.writer import Writer

    path = tmp_path / "u.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="sigma_des")
        w.add_metadata("sigma_des", {"recording": "{}", "scenario": "{}"})
        cid = w.register_channel("/none/state", "json",
                                 w.register_schema("foo.Bar", "jsonschema", b"{}"))
        w.add_message(cid, 0, b"{}", 0)
        w.finish()
    assert main(["replay", str(path), "--rate", "60", "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "unknown schema 'foo.Bar'" in err


def test_existing_output_is_not_overwritten_unless_forced(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _record(path)
    out = tmp_path / "traj.csv"
    out.write_text("precious\n")
    assert main(["replay", str(path), "--rate", "60", "--out", str(out)]) == 2
    assert out.read_text() == "precious\n"
    assert main(["replay", str(path), "--rate", "60", "--out", str(out), "--force"]) == 0
    assert out.read_text().startswith("method,node,t")
