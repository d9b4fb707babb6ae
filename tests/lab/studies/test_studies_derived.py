"""studies/derived.py: the metrics derived from a render-tick series, by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sigma_lab.studies.derived import DERIVED_UNITS, derived_metrics, seed_means, window_stats


def test_derived_metrics_of_a_hand_made_series() -> None:
    ts = {
        "t": np.array([0.0, 0.25, 0.5, 0.75, 1.0]),
        "f_trig": np.array([100.0, 100.0, 50.0, 50.0, 50.0]),
        "spread": np.array([0.0, 1.0, 2.0, 0.0, 0.0]),
        "aligned_frame": np.array([0.0, 10.0, 30.0, 30.0, 40.0]),
        "aoi_mean": np.array([0.01, 0.03, math.nan, 0.01, 0.03]),
    }
    m = derived_metrics(ts, {})
    assert set(m) == set(DERIVED_UNITS)
    # displacement = spread / f_trig in ms: 0, 10, 40, 0, 0
    assert m["displacement_mean_ms"] == pytest.approx(10.0)
    assert m["displacement_max_ms"] == pytest.approx(40.0)
    assert m["f_trig_window_min_hz"] == 50.0
    assert m["f_trig_settled_hz"] == 50.0  # median of the last quarter (ticks 3, 4)
    # aligned frames advance 40, 80, 0, 40 per second over 0.25 s windows
    assert m["aligned_rate_hz"] == pytest.approx(40.0)
    assert m["aligned_rate_std_hz"] == pytest.approx(math.sqrt(800.0))
    # per-tick mean AoI 10, 30, 10, 30 ms (NaN dropped): std 10 ms
    assert m["aoi_tick_mean_std_ms"] == pytest.approx(10.0)


def test_an_empty_series_gives_nan_for_every_metric() -> None:
    empty = {k: np.empty(0) for k in ("t", "f_trig", "spread", "aligned_frame", "aoi_mean")}
    assert all(math.isnan(v) for v in derived_metrics(empty, {}).values())


def test_window_stats_before_during_after_and_recovery() -> None:
    ts = {
        "t": np.arange(7, dtype=float),
        "aoi_mean": np.array([0.01, 0.01, 0.05, 0.05, 0.03, 0.01, 0.01]),
        "aligned_frame": np.array([0.0, 10.0, 10.0, 10.0, 20.0, 30.0, 40.0]),
    }
    w = window_stats(ts, 2.0, 4.0)
    assert w["aoi_before_ms"] == pytest.approx(10.0) and w["aoi_during_ms"] == pytest.approx(50.0)
    assert w["aoi_after_ms"] == pytest.approx(10.0)  # "after" starts 0.5 s after the window
    assert w["aoi_max_during_ms"] == pytest.approx(50.0)
    assert (w["aligned_rate_before_hz"], w["aligned_rate_during_hz"]) == (10.0, 0.0)
    assert w["aligned_rate_after_hz"] == 10.0
    # back within 1.5 x the pre-fault median (10 ms) first at t = 5: 1 s after the window
    assert w["recovery_s"] == 1.0
    assert math.isnan(window_stats(ts, 2.0, 6.0)["recovery_s"])  # fault lasts to the end


def test_seed_means_leave_nan_out() -> None:
    got = seed_means([{"a": 1.0, "b": math.nan}, {"a": 3.0, "b": math.nan}, {"a": 5.0, "b": 2.0}])
    assert got == {"a": 3.0, "b": 2.0}
    assert math.isnan(seed_means([{"a": math.nan}])["a"])
