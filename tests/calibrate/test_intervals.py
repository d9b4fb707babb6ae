"""Prediction intervals: residual bounds by hand, their coverage on synthetic residuals
whose distribution is known, the interval's two parts, regimes and the residual file."""

from __future__ import annotations

import math
import statistics
from pathlib import Path

import numpy as np
import pytest

from sigma_des.calibrate.intervals import (
    COVERAGE,
    Residual,
    interval,
    load_residuals,
    lookup,
    pooled_residuals,
    rate_regime,
    regime,
    residual_bounds,
    residuals_toml,
)
from sigma_des.errors import ConfigError


def test_residual_bounds_are_the_kth_order_statistics() -> None:
    # n = 19, coverage 0.8: k = floor(20 * 0.1) = 2 -> the 2nd smallest and 2nd largest
    vals = [float(v) for v in range(19)][::-1]
    assert residual_bounds(vals, 0.8) == (1.0, 17.0, True)
    # n = 9: k = floor(10 * 0.1) = 1 -> min and max
    assert residual_bounds([0.3, -0.1, 0.2, 0.0, 0.1, -0.2, 0.4, -0.3, 0.5], 0.8) == (
        -0.3, 0.5, True)
    # n = 5: k = floor(6 * 0.1) = 0 -> too few: the range, said
    assert residual_bounds([0.1, -0.2, 0.05, math.nan, 0.3, 0.0], 0.8) == (-0.2, 0.3, False)
    with pytest.raises(ValueError):
        residual_bounds([math.nan], 0.8)
    with pytest.raises(ValueError):
        residual_bounds([0.1], 1.0)


def test_coverage_on_synthetic_residuals_is_the_stated_one() -> None:
    """Residuals r ~ 0.1 + 0.2 * t(3) (skewed use: live = DES / (1 + r) needs r > -1,
    clipped far in the tail). With n = 199 calibration residuals, k = 20: a new cell's
    live value is inside with probability (n + 1 - 2k) / (n + 1) = 0.8 exactly, whatever
    the distribution; averaged over 400 validations x 500 new cells."""
    rng = np.random.default_rng(7)

    def draw(size: int) -> np.ndarray:
        return np.clip(0.1 + 0.2 * rng.standard_t(3, size), -0.9, None)

    hits = []
    widths = []
    for _ in range(400):
        lo, hi, enough = residual_bounds(draw(199).tolist(), 0.8)
        assert enough
        res = Residual("aoi_mean", "any", lo, hi, 199, True, "synthetic")
        live = 20.0 + 5.0 * rng.random(500)
        des = live * (1.0 + draw(500))
        for d, x in zip(des[:50], live[:50], strict=True):  # the interval, by its formula
            iv = interval("aoi_mean", [float(d)], res, 0.8)
            assert (iv.lo <= x <= iv.hi) == (lo <= d / x - 1.0 <= hi)
        inside = (des / (1.0 + hi) <= live) & (live <= des / (1.0 + lo))
        hits.append(inside.mean())
        widths.append(hi - lo)
    assert statistics.fmean(hits) == pytest.approx(0.8, abs=0.01)
    # the 10th-90th percentile width of 0.2 t(3) is 2 * 0.2 * 1.638 = 0.655
    assert statistics.median(widths) == pytest.approx(0.655, rel=0.1)


def test_interval_joins_seed_spread_and_residuals_by_hand() -> None:
    res = Residual("latency_state_mean", "node-below", -0.2, 0.5, 10, True, "hand")
    iv = interval("latency_state_mean", [2.0, 4.0, math.nan], res, 0.8)
    h = 1.2815515655446004 * math.sqrt(2.0)  # z(0.9) x the seeds' sd
    assert (iv.mean, iv.sd) == (3.0, pytest.approx(math.sqrt(2.0)))
    assert iv.lo == pytest.approx((3.0 - h) / 1.5)
    assert iv.hi == pytest.approx((3.0 + h) / 0.8)
    one = interval("latency_state_mean", [3.0], res, 0.8)  # one seed: residuals alone
    assert (one.lo, one.hi) == (pytest.approx(2.0), pytest.approx(3.75))
    pp = Residual("missed_frac", "any", -10.0, 4.0, 10, True, "hand")
    m = interval("missed_frac", [0.02], pp, 0.8)  # live = DES - r / 100, clipped to 0..1
    assert (m.lo, m.hi) == (0.0, pytest.approx(0.12))
    bare = interval("aoi_mean", [5.0], None)
    assert (bare.lo, bare.hi, bare.residual) == (5.0, 5.0, None)
    assert math.isnan(interval("aoi_mean", [math.nan], res).mean)


def test_missed_frame_interval_reaches_one_frame_of_the_window() -> None:
    # residuals all 0 (a regime where neither misses): the residuals alone give [m, m]
    zero = Residual("missed_frac", "node-below", 0.0, 0.0, 40, True, "hand")
    assert interval("missed_frac", [0.0], zero).hi == 0.0
    # 300 frames (100 Hz x a 3 s window): one frame is 1/300 either side, clipped at 0
    iv = interval("missed_frac", [0.0], zero, frames=300.0)
    assert (iv.lo, iv.hi) == (0.0, pytest.approx(1 / 300))
    mid = interval("missed_frac", [0.01], zero, frames=300.0)
    assert (mid.lo, mid.hi) == (pytest.approx(0.01 - 1 / 300), pytest.approx(0.01 + 1 / 300))
    # residuals reaching further than a frame keep their bounds: -0.5 pp .. +2 pp
    wide = Residual("missed_frac", "node-near", -0.5, 2.0, 40, True, "hand")
    w = interval("missed_frac", [0.05], wide, frames=300.0)
    assert (w.lo, w.hi) == (pytest.approx(0.03), pytest.approx(0.055))
    # other metrics are not in frames: the same interval with or without
    res = Residual("aoi_mean", "node-below", -0.1, 0.1, 40, True, "hand")
    assert interval("aoi_mean", [10.0], res, frames=300.0) == interval("aoi_mean", [10.0], res)


def test_a_rate_not_held_is_read_among_the_rates_not_held() -> None:
    """Below 95 % of the nominal rate the trigger rate's regime is the mode's
    ``limited`` one, whatever the machine; at or above it, the regime as it is."""
    assert rate_regime("node-below", 94.9, 100.0) == "node-limited"
    assert rate_regime("bundle-near", 3.0, 100.0) == "bundle-limited"
    assert rate_regime("node-near", 95.0, 100.0) == "node-near"
    assert rate_regime("node-below", 47.4, 50.0) == "node-limited"
    assert rate_regime("node-below", 47.5, 50.0) == "node-below"
    assert rate_regime("bundle-below", math.nan, 100.0) == "bundle-below"
    res = {("trigger_rate_hz", "node-limited"): Residual("trigger_rate_hz", "node-limited",
                                                         -0.2, 0.1, 40, True, "")}
    iv = interval("trigger_rate_hz", [80.0], lookup(res, "trigger_rate_hz",
                                                    rate_regime("node-below", 80.0, 100.0)))
    assert (iv.lo, iv.hi) == pytest.approx((80.0 / 1.1, 80.0 / 0.8))


def test_a_trigger_rate_interval_reaches_one_trigger_of_the_window() -> None:
    """Residuals all 0 (held rates): the interval of a 100 Hz prediction over a 3 s
    window is [100 - 1/3, 100 + 1/3]; wider residuals are kept; no window, no floor."""
    zero = Residual("trigger_rate_hz", "node-below", 0.0, 0.0, 40, True, "")
    iv = interval("trigger_rate_hz", [100.0], zero, window=3.0)
    assert (iv.lo, iv.hi) == pytest.approx((100.0 - 1.0 / 3.0, 100.0 + 1.0 / 3.0))
    assert (interval("trigger_rate_hz", [100.0], zero).lo,
            interval("trigger_rate_hz", [100.0], zero).hi) == (100.0, 100.0)
    wide = Residual("trigger_rate_hz", "node-limited", -0.2, 0.25, 40, True, "")
    iv = interval("trigger_rate_hz", [60.0], wide, window=3.0)
    assert (iv.lo, iv.hi) == pytest.approx((60.0 / 1.25, 60.0 / 0.8))
    # no method triggers faster than f_trig: the interval stops there
    iv = interval("trigger_rate_hz", [95.0], wide, window=3.0, f_trig=100.0)
    assert (iv.lo, iv.hi) == pytest.approx((95.0 / 1.25, 100.0))
    # the floor is the trigger rate's only: a latency keeps its zero-width interval
    lat = Residual("latency_state_mean", "node-below", 0.0, 0.0, 40, True, "")
    iv = interval("latency_state_mean", [2.0], lat, window=3.0)
    assert (iv.lo, iv.hi) == (2.0, 2.0)


def test_regime_and_lookup_order() -> None:
    assert regime(False, 0.5, 0.0) == "node-below"
    assert regime(False, 0.7, 0.0) == "node-near"
    assert regime(True, math.nan, 0.01) == "bundle-near"
    assert regime(True, math.nan, math.nan) == "bundle-below"
    r = {k: Residual(k[0], k[1], -0.1, 0.1, 1, True, "") for k in
         [("aoi_mean", "node-near"), ("aoi_mean", "node-any"), ("aoi_mean", "any"),
          ("aoi_p99", "bundle-any")]}
    assert lookup(r, "aoi_mean", "node-near").regime == "node-near"  # type: ignore[union-attr]
    assert lookup(r, "aoi_mean", "node-below").regime == "node-any"  # type: ignore[union-attr]
    assert lookup(r, "aoi_mean", "bundle-near").regime == "any"  # type: ignore[union-attr]
    assert lookup(r, "aoi_p99", "node-below") is None


def test_residual_file_round_trip_and_the_shipped_one(tmp_path) -> None:  # type: ignore[no-untyped-def]
    vals = {("aoi_mean", "node-below"): [float(v) / 100 for v in range(-9, 10)],
            ("missed_frac", "any"): [0.0, 1.5, math.nan]}
    p = tmp_path / "residuals.toml"
    p.write_text(residuals_toml(vals, {"coverage": 0.8, "source": 'run "x"'}))
    table, meta = load_residuals(p)
    assert meta == {"coverage": 0.8, "source": 'run "x"'}
    a = table[("aoi_mean", "node-below")]
    assert (a.lo, a.hi, a.n, a.enough) == (-0.08, 0.08, 19, True)
    assert (table[("missed_frac", "any")].n, table[("missed_frac", "any")].enough) == (2, False)
    shipped, meta = load_residuals()
    assert meta["coverage"] == COVERAGE  # written by the suite at the build coverage
    for r in shipped.values():  # every entry says where it comes from
        assert r.source and r.n > 0
    for metric in ("aoi_mean", "aoi_p99", "latency_state_mean", "trigger_rate_hz",
                   "missed_frac"):
        for reg in ("node-below", "node-near", "bundle-below", "bundle-near"):
            assert lookup(shipped, metric, reg) is not None
    p.write_text('[[residual]]\nmetric = "aoi_mean"\nregime = "any"\nlo = 0.2\nhi = 0.1\n')
    with pytest.raises(ConfigError, match="residuals"):
        load_residuals(p)


def test_pooled_residuals_join_each_metric_and_regimes_values(tmp_path: Path) -> None:
    """Two files: a key in both gets both lists joined in order (so its bounds are the
    k-th order statistics of the union), a key in one keeps its values; files built for
    different coverages are refused."""
    a, b, c = tmp_path / "a.toml", tmp_path / "b.toml", tmp_path / "c.toml"
    a.write_text(residuals_toml({("aoi_mean", "any"): [0.1, -0.2],
                                 ("aoi_p99", "any"): [0.3]},
                                {"coverage": 0.85, "source": "one"}))
    b.write_text(residuals_toml({("aoi_mean", "any"): [0.05, 0.4, -0.1]},
                                {"coverage": 0.85, "source": "two"}))
    c.write_text(residuals_toml({("aoi_mean", "any"): [0.0]},
                                {"coverage": 0.8, "source": "three"}))
    p = tmp_path / "p.toml"
    p.write_text(pooled_residuals([a, b]))
    table, meta = load_residuals(p)
    assert table[("aoi_mean", "any")].n == 5 and table[("aoi_p99", "any")].n == 1
    assert "0.1, -0.2, 0.05, 0.4, -0.1" in p.read_text()
    assert meta["coverage"] == 0.85 and meta["source"] == "one; two"
    assert meta["validations"] == 2
    # a pooled file pooled again: its validations count, its values join in order
    q = tmp_path / "q.toml"
    q.write_text(pooled_residuals([b, p]))
    table, meta = load_residuals(q)
    assert meta["validations"] == 3 and "3 validations" in meta["kind"]
    assert table[("aoi_mean", "any")].n == 8
    assert "0.05, 0.4, -0.1, 0.1, -0.2, 0.05, 0.4, -0.1" in q.read_text()
    assert "cross_pairs" not in meta
    # the shipped file's cross-session pairs are kept, not dropped
    shipped = tmp_path / "shipped.toml"
    shipped.write_text(residuals_toml({("aoi_mean", "any"): [0.2]},
                                      {"coverage": 0.85, "validations": 3, "cross_pairs": 6}))
    r = tmp_path / "r.toml"
    r.write_text(pooled_residuals([shipped, a]))
    _t, meta = load_residuals(r)
    assert (meta["validations"], meta["cross_pairs"]) == (4, 6)
    assert meta["kind"].endswith("4 validations and 6 cross-session pairs")
    with pytest.raises(ConfigError, match="coverages"):
        pooled_residuals([a, c])
    bad = tmp_path / "bad.toml"  # a count that is not an integer >= 1 is refused by name
    bad.write_text(residuals_toml({("aoi_mean", "any"): [0.0]},
                                  {"coverage": 0.85, "validations": 0}))
    with pytest.raises(ConfigError, match=r"meta\.validations must be an integer >= 1, got 0"):
        pooled_residuals([a, bad])
    bounds = tmp_path / "bounds.toml"  # bounds alone cannot be pooled: refused, not skipped
    bounds.write_text('[[residual]]\nmetric = "aoi_mean"\nregime = "any"\nlo = -0.1\n'
                      'hi = 0.1\n')
    with pytest.raises(ConfigError, match="no values to pool"):
        pooled_residuals([a, bounds])
