"""compare --out draws the comparison's plots; --no-plots skips them (issue 9.13)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import sigma_des.plots as plots
from sigma_des.cli import main

SETS = ["--set", "nodes=3", "--set", "duration=1.0", "--set", "warmup=0.2",
        "--set", "dynamics=pointmass", "--set", "fidelity.enabled=false", "--no-progress",
        "--methods", "none,bides"]


def test_compare_out_writes_the_plots(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "o"
    old = os.umask(0o022)
    try:
        assert main(["compare", *SETS, "--out", str(out)]) == 0
    finally:
        os.umask(old)
    assert "plots: aoi_dist.png, aoi_time.png, trigger_rate.png, spread.png" in (
        capsys.readouterr().out
    )
    for name in plots.PLOTS:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*plots.PLOTS, "results.csv", "summary.json", "wall.csv"]
    )  # no temporary left behind
    # readable by others as umask 022 says, not 0600 as mkstemp makes them (issue 22.8)
    assert {p.name: oct(p.stat().st_mode & 0o777) for p in out.iterdir()} == {
        p.name: "0o644" for p in out.iterdir()}


def test_no_plots(tmp_path: Path) -> None:
    """``--no-plots`` writes the tables only (a missing matplotlib: tests/test_extras.py)."""
    a = tmp_path / "a"
    assert main(["compare", *SETS, "--out", str(a), "--no-plots"]) == 0
    assert (a / "results.csv").exists() and not any(p.suffix == ".png" for p in a.iterdir())


def test_rate_series_exact() -> None:
    """A counter advancing 1 per 10 ms, sampled every 40 ms: 100/s in every window."""
    t = np.arange(0, 1.0, 0.04)
    t_end, rate = plots.rate_series(t, t * 100.0, window=0.2)
    assert t_end[0] == t[5] and np.allclose(rate, 100.0)
    assert plots.rate_series(np.array([0.0]), np.array([1.0]))[0].size == 0


def test_moving_average_exact() -> None:
    """Centred window of 3, NaN ignored, shorter windows at the ends."""
    x = np.array([1.0, 2.0, np.nan, 4.0, 6.0])
    got = plots.moving_average(x, 3)
    assert got.tolist() == [1.5, 1.5, 3.0, 5.0, 5.0]
    assert plots.moving_average(x, 1)[1] == 2.0
    assert np.isnan(plots.moving_average(np.array([np.nan, np.nan]), 2)).all()


def test_moving_average_keeps_a_short_series_length() -> None:
    """A series shorter than the window (a run stopped early) keeps its own length."""
    got = plots.moving_average(np.array([1.0, 2.0, 3.0]), 12)
    assert got.tolist() == [1.5, 2.0, 2.5]  # the window shrinks to the 3 samples
