"""In-sample cells no calibration can bring within 10 % of every run: live's repeats of
one setting too far apart, by hand."""

from __future__ import annotations

import pytest

from sigma_des.calibrate.insample import apart_text, repeats_apart
from sigma_des.calibrate.report import report_lines

RUNS = {"r1": {"nodes": 20, "hosts": 2, "bundle": False},
        "r2": {"nodes": 20, "hosts": 2, "bundle": False},
        "r3": {"nodes": 20, "hosts": 2, "bundle": False},
        "b1": {"nodes": 40, "hosts": 2, "bundle": True}}


def _row(run: str, metric: str, live: float, des: float, method: str = "lockstep") -> dict:
    err = des - live if metric == "missed_frac" else (des - live) / live
    return {"run": run, "method": method, "metric": metric, "live": live, "des": des,
            "error": err, "flagged": abs(err) > 0.10}


def test_repeats_more_than_22_percent_apart_are_named_and_others_not() -> None:
    rows = [
        # 2.445 / 1.849 = 1.322 > 1.1 / 0.9: no value within 10 % of both ends
        _row("r1", "latency_state_mean", 2.154, 2.13),
        _row("r2", "latency_state_mean", 1.849, 2.13),
        _row("r3", "latency_state_mean", 2.445, 2.13),
        # 1.2 apart: 1.09 is within 10 % of 1.0 and of 1.2, so attainable
        _row("r1", "aoi_mean", 10.0, 10.9), _row("r2", "aoi_mean", 12.0, 10.9),
        _row("r3", "aoi_mean", 11.0, 10.9),
        # 25 pp apart: over 2 x 10 pp; 20 pp (HLC) is exactly attainable (10 % between)
        _row("r1", "missed_frac", 0.0, 0.1), _row("r2", "missed_frac", 0.25, 0.1),
        _row("r1", "missed_frac", 0.0, 0.1, "hlc"), _row("r2", "missed_frac", 0.2, 0.1, "hlc"),
        # the bundled run has no repeat: nothing to say whatever its error
        _row("b1", "latency_state_mean", 1.0, 2.0),
    ]
    apart = repeats_apart({"runs": RUNS, "in_sample": rows})
    assert [(g["setting"], g["method"], g["metric"]) for g in apart] == [
        ("N = 20, 2 hosts, per node", "lockstep", "latency_state_mean"),
        ("N = 20, 2 hosts, per node", "lockstep", "missed_frac")]
    lat, missed = apart
    assert lat["live"] == [2.154, 1.849, 2.445] and lat["runs"] == ["r1", "r2", "r3"]
    assert lat["apart"] == pytest.approx(2.445 / 1.849 - 1)
    assert lat["flagged"] == 2  # 2.13 is 15 % above 1.849 and 13 % below 2.445
    assert missed["apart"] == pytest.approx(0.25) and missed["flagged"] == 1
    # the words both reports print: per cent for a ratio, points for missed frames
    assert apart_text(lat) == ("N = 20, 2 hosts, per node, lockstep latency_state_mean: "
                               "2.154 / 1.849 / 2.445 (32 %)")
    assert apart_text(missed) == ("N = 20, 2 hosts, per node, lockstep missed_frac: "
                                  "0 / 0.25 (25 pp)")


def test_the_report_counts_the_flagged_cells_of_such_settings() -> None:
    rows = [_row("r1", "latency_state_mean", 2.0, 2.1),
            _row("r2", "latency_state_mean", 1.5, 2.1), _row("b1", "aoi_mean", 10.0, 12.0)]
    lines = report_lines({"runs": RUNS, "in_sample": rows})
    assert "in-sample: 1 of 3 cells within 10 % (10 pp)" in lines
    assert ("in-sample: 1 of the 2 flagged cells are runs of a setting whose live repeats "
            "are more than 22 % (20 pp) apart: no one value is within 10 % of each") in lines
    assert ("live repeats apart: N = 20, 2 hosts, per node, lockstep latency_state_mean: "
            "2 / 1.5 (33 %)") in lines


def test_a_single_run_calibration_says_nothing_of_repeats() -> None:
    rows = [_row("r1", "latency_state_mean", 2.0, 3.0)]
    assert repeats_apart({"runs": RUNS, "in_sample": rows}) == []
    assert repeats_apart({"in_sample": [{**rows[0], "run": None}]}) == []
    assert not [x for x in report_lines({"in_sample": rows}) if "apart" in x]
