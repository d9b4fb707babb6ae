"""studies/plots.py: study figures in the house style, legible at --quick."""

from __future__ import annotations

import argparse
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sigma_lab import studies

from sigma_des.plotstyle import COLORS


@pytest.fixture(scope="module")
def study() -> studies.Study:
    from sigma_des.api import compare
    from sigma_des.config import load

    sc = load(None, ["nodes=3", "duration=1.0", "warmup=0.2", "dynamics=pointmass",
                     "fidelity.enabled=false"])
    res = compare(sc, ["none", "lockstep", "bides"], progress=False)
    st = studies.Study("t", argparse.Namespace(quick=True, seeds=[1]), {"v": sc})
    st.records = [studies.RunRecord("v", 1, m, res, studies.MethodSpec(m, m)) for m in res.methods]
    return st


def _png_size(path: Path) -> tuple[int, int]:
    w, h = struct.unpack(">II", path.read_bytes()[16:24])
    return w, h


def test_quick_plots_are_legible(study: studies.Study, tmp_path: Path) -> None:
    plt = studies.plot_setup(fast=True)
    fig, axs = plt.subplots(1, 2, figsize=(8, 3))
    studies.bar_panels(axs, study, "v", [("aoi_mean", 1.0, "ms"), ("throughput_mbps", 1.0, "")])
    fig.suptitle("a long suptitle that must not overlap the panel titles")
    assert [ax.get_title() for ax in axs] == ["AoI, mean", "Wire throughput"]
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    sup = fig._suptitle.get_window_extent(r)  # noqa: SLF001 - matplotlib has no getter
    for ax in axs:
        assert not sup.overlaps(ax.title.get_window_extent(r))
    path = studies.save(fig, tmp_path, "m.png")
    assert _png_size(path) == (800, 300)  # 100 dpi, not the old 50


def test_study_aoi_time_in_house_style(study: studies.Study) -> None:
    plt = studies.plot_setup(fast=True)
    fig, ax = plt.subplots()
    try:
        studies.plot_aoi_time(ax, study, "v")
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        assert lines["none (mean over nodes)"].get_color() == COLORS["none"]
        twin = "bides (mean over nodes) (= lockstep)"
        assert twin in lines and lines[twin].get_color() == COLORS["bides"]
        assert np.allclose(lines[twin].get_ydata(),
                           lines["lockstep (mean over nodes)"].get_ydata(), equal_nan=True)
    finally:
        plt.close(fig)


def test_study_rate_plot_names_coinciding_labels(study: studies.Study) -> None:
    plt = studies.plot_setup(fast=True)
    fig, ax = plt.subplots()
    try:
        studies.plot_rate(ax, study, "v", "latest_trigger", 0.5)
        labels: list[Any] = [ln.get_label() for ln in ax.get_lines()]
        assert labels == ["none", "lockstep (= none)", "bides (= none)"]
    finally:
        plt.close(fig)
