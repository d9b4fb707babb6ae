"""``calibrate`` given a corrupt ``.mcap`` (issue 26): exit 2 and one line naming the
file, whatever the damage (empty, random bytes, the magic then garbage, any cut)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigma_des.cli import main

SMALL = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2", "--set",
         "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
         "--methods", "none,bides"]
MAGIC = b"\x89MCAP0\r\n"


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("rec") / "r.mcap"
    assert main(["compare", *SMALL, "--record", str(path)]) == 0
    return path.read_bytes()


def _refused(f: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["calibrate", str(f), "--no-check"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith(f"sigma-des: error: {f}: "), err
    return err


@pytest.mark.parametrize(("data", "want"), [
    (b"", "not a readable MCAP file (no MCAP magic at the start)"),
    (np.random.default_rng(3).bytes(4096), "not a readable MCAP file (no MCAP magic at the start)"),
    (MAGIC, "corrupt MCAP file"),
    (MAGIC + np.random.default_rng(4).bytes(4096), "truncated or unfinished recording"),
])
def test_not_a_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str], data: bytes,
                         want: str) -> None:
    f = tmp_path / "x.mcap"
    f.write_bytes(data)
    assert want in _refused(f, capsys)


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.0, 1.0, exclude_max=True))
def test_a_recording_cut_anywhere(good: bytes, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str], keep: float) -> None:
    f = tmp_path / "cut.mcap"
    f.write_bytes(good[: int(len(good) * keep)])
    err = _refused(f, capsys)
    assert "MCAP" in err or "truncated" in err
