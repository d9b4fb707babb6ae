"""plotstyle: one palette for every plot, coinciding curves found, fixed rate axes."""

from __future__ import annotations

import numpy as np
import sigma_lab.studies as studies
import sigma_lab.studies.plots as study_plots

import sigma_des.plotstyle as ps


def test_one_palette_object_for_compare_and_studies() -> None:
    assert studies.COLORS is ps.COLORS and study_plots.COLORS is ps.COLORS
    assert ps.COLORS["bides"] == ps.STYLES["bides"].color == "#009E73"
    # every method has its own colour, line style and marker
    for attr in ("color", "marker"):
        values = [getattr(s, attr) for s in ps.STYLES.values()]
        assert len(set(values)) == len(values), attr


def test_coinciding_names_the_first_equal_curve() -> None:
    a = np.array([1.0, 2.0, np.nan])
    got = ps.coinciding({
        "none": a, "lockstep": a + 5.0, "hlc": a * (1 + 1e-9), "bides": a + 5.0,
        "short": a[:2],
    })
    assert got == {"hlc": "none", "bides": "lockstep"}  # NaN equals NaN; lengths differ
    assert ps.coinciding({"none": a, "bides": a + 1e-3}) == {}
    assert ps.method_label("bides", got, " (mean)") == "bides (mean) (= lockstep)"
    assert ps.method_label("none", got) == "none"


def test_rate_ylim_is_fixed_around_the_set_rate() -> None:
    assert ps.rate_ylim([100.0]) == (0.0, 130.0)
    # counting noise of +-1 Hz does not move the axis
    assert ps.rate_ylim([100.0], [np.array([99.0, 101.0, np.nan])]) == (0.0, 130.0)
    # an achieved rate above the range widens it to show it
    assert ps.rate_ylim([100.0, 50.0], [np.array([200.0])]) == (0.0, 210.0)
    assert ps.rate_ylim([float("nan")]) == (0.0, 1.0)


def test_spread_shares() -> None:
    levels, shares = ps.spread_shares(np.array([0.0, 1.0, 1.0, 0.0, 1.0, 3.0, np.nan, 1.0]))
    assert levels.tolist() == [0, 1, 3]
    assert shares.tolist() == [2 / 7, 4 / 7, 1 / 7]
    assert ps.spread_shares(np.array([np.nan]))[0].size == 0


def test_line_kw_keeps_coinciding_markers_apart() -> None:
    a, b = ps.line_kw("lockstep", 1, 120), ps.line_kw("bides", 3, 120)
    assert (a["color"], a["ls"], a["marker"]) == ("#D55E00", "--", "s")
    assert a["markevery"] == (2, 10) and b["markevery"] == (6, 10)
    assert a["ms"] != b["ms"]
    # labels that are not methods get distinct styles by index
    assert ps.line_kw("bides_mqtt", 0)["color"] != ps.line_kw("lockstep_dds", 1)["color"]


def test_metric_titles_are_human() -> None:
    assert ps.metric_title("aoi_mean") == "AoI, mean"
    assert ps.metric_title("buffer_bytes_peak") == "Alignment buffer, peak"
    assert ps.metric_title("some_new_metric") == "Some new metric"
