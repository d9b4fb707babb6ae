"""compare --out draws the comparison's plots; --no-plots skips them (issue 9.13)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

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


# ---------------------------------------------------------------- plot content

@pytest.fixture(scope="module")
def res() -> Any:
    from sigma_des.api import compare
    from sigma_des.config import load

    sc = load(None, ["nodes=3", "duration=1.5", "warmup=0.2", "dynamics=pointmass",
                     "fidelity.enabled=false"])
    return compare(sc, ["none", "lockstep", "bides"], progress=False)


def _legend_texts(ax: Any) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _legend_is_outside(fig: Any, ax: Any) -> bool:
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    return ax.get_legend().get_window_extent(r).x0 >= ax.get_window_extent(r).x1


def test_compare_rate_plot_has_a_fixed_axis_and_house_colours(res: Any) -> None:
    import matplotlib.pyplot as plt

    from sigma_des.plotstyle import COLORS

    fig = plots.draw("trigger_rate.png", res)
    try:
        ax = fig.axes[0]
        assert ax.get_ylim() == (0.0, 1.3 * res.scenario.f_trig)
        by_label = {ln.get_label(): ln for ln in ax.get_lines()}
        assert by_label["none achieved"].get_color() == COLORS["none"]
        assert by_label["bides achieved (= none)"].get_color() == COLORS["bides"]
        assert "set rate (all methods)" in _legend_texts(ax)
        assert _legend_is_outside(fig, ax)
    finally:
        plt.close(fig)


def test_compare_coinciding_methods_are_named_and_visible(res: Any) -> None:
    import matplotlib.pyplot as plt

    fig = plots.draw("aoi_time.png", res)
    try:
        ax = fig.axes[0]
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        # lockstep and bides show the same AoI on this loss-free network
        lock = np.asarray(lines["lockstep (mean)"].get_ydata())
        twin = next(k for k in lines if k.startswith("bides"))
        assert np.allclose(lock, lines[twin].get_ydata(), equal_nan=True)
        assert twin == "bides (mean) (= lockstep)"
        # drawn differently: line style and marker positions
        assert lines["lockstep (mean)"].get_linestyle() != lines[twin].get_linestyle()
        assert lines["lockstep (mean)"].get_markevery() != lines[twin].get_markevery()
        assert _legend_is_outside(fig, ax)
    finally:
        plt.close(fig)


def test_compare_spread_is_a_distribution_and_a_moving_mean(res: Any) -> None:
    import matplotlib.pyplot as plt

    fig = plots.draw("spread.png", res)
    try:
        ax_d, ax_t = fig.axes
        for m in res.methods:  # bar heights of one method sum to 1 (shares of ticks)
            bars = next(c for c in ax_d.containers if c.get_label() == m)
            assert sum(b.get_height() for b in bars) == pytest.approx(1.0)
        for ln in ax_t.get_lines():  # moving mean: within [0, max spread], not a 0/1 comb
            y = np.asarray(ln.get_ydata(), dtype=float)
            spread = np.asarray(res.timeseries[ln.get_label().split()[0]]["spread"], float)
            assert np.nanmax(y) <= np.nanmax(spread) + 1e-12
            jumps = np.abs(np.diff(y[np.isfinite(y)]))
            assert jumps.size == 0 or jumps.max() < 0.5
    finally:
        plt.close(fig)


def test_pngs_follow_the_umask(tmp_path: Path) -> None:
    import os
    import stat

    out = tmp_path / "o"
    old = os.umask(0o022)
    try:
        assert main(["compare", *SETS, "--out", str(out)]) == 0
    finally:
        os.umask(old)
    for name in plots.PLOTS:
        assert stat.S_IMODE((out / name).stat().st_mode) == 0o644, name
        head = (out / name).read_bytes()[:24]
        assert head[:8] == b"\x89PNG\r\n\x1a\n"
        assert (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")) == (
            900, 400)  # 9 x 4 in at 100 dpi


@pytest.mark.parametrize("mode, label", [("des", "simulated time (s)"),
                                         ("live", "run time (s, wall clock)")])
def test_time_axes_say_whose_clock(res: Any, mode: str, label: str) -> None:
    """A live run's series are stamped by the wall clock: its plots must not say 'simulated'."""
    import dataclasses

    import matplotlib.pyplot as plt

    run = dataclasses.replace(res, mode=mode)
    for name in ("aoi_time.png", "trigger_rate.png", "spread.png"):
        fig = plots.draw(name, run)
        try:
            assert fig.axes[-1].get_xlabel() == label
        finally:
            plt.close(fig)
