"""The validation suite's pure rules, by hand: errors, noise floor, verdicts, knee, grid."""

from __future__ import annotations

import math

import pytest
from sigma_lab.studies.validation.grid import Plan, full_plan, hosts_for, quick_plan
from sigma_lab.studies.validation.scoring import (
    Verdict,
    error,
    judge,
    knee,
    knee_of,
    knee_verdict,
    live_repeats,
    noise_floor,
    share,
)

from sigma_des.errors import ConfigError


def test_error_relative_and_in_percentage_points() -> None:
    assert error("aoi_mean", 20.0, 23.0) == pytest.approx(0.15)
    assert error("latency_state_mean", 4.0, 3.0) == pytest.approx(-0.25)
    assert error("missed_frac", 0.02, 0.10) == pytest.approx(8.0)  # pp
    assert error("missed_frac", 0.0, 0.0) == 0.0  # live missing none is fine in pp
    assert math.isnan(error("aoi_mean", 0.0, 3.0))
    assert math.isnan(error("aoi_mean", math.nan, 3.0))


def test_noise_floor_is_range_over_mean() -> None:
    assert noise_floor("aoi_mean", [10.0, 12.0, 14.0]) == pytest.approx(4.0 / 12.0)
    assert noise_floor("missed_frac", [0.0, 0.03, 0.01]) == pytest.approx(3.0)
    assert noise_floor("aoi_mean", [10.0, math.nan, 14.0]) == pytest.approx(4.0 / 12.0)
    assert math.isnan(noise_floor("aoi_mean", [10.0]))
    assert math.isnan(noise_floor("aoi_mean", [0.0, 0.0]))


def test_live_repeats_read_back_as_written() -> None:
    # cells.csv keeps a cell's runs space-joined; a once-run cell has one
    assert live_repeats({"live_runs": "12.5 13 1e-05"}) == [12.5, 13.0, 1e-05]
    assert live_repeats({"live_runs": 7.25}) == [7.25]


def test_judge_band_and_the_live_range_rule() -> None:
    assert judge("aoi_mean", 100.0, 114.0) == Verdict(True, True, True, "band")
    assert judge("aoi_mean", 100.0, 116.0, floor=0.05) == Verdict(True, False, False, "band")
    # live moved 30 % between the calibration setting's repeats: a cell run once is
    # still judged by the band alone (a borrowed floor is no licence)
    assert judge("aoi_mean", 100.0, 125.0, floor=0.30) == Verdict(True, False, False, "band")
    assert judge("aoi_mean", 100.0, 125.0, floor=0.30, repeats=[110.0]) == Verdict(
        True, False, False, "band")  # one run of its own: no range
    # two runs of its own, 80 and 120 (mean 100): inside their range passes
    assert judge("aoi_mean", 100.0, 119.0, 0.4, repeats=[80.0, 120.0]) == Verdict(
        True, True, False, "live range")
    assert not judge("aoi_mean", 100.0, 121.0, 0.4, repeats=[80.0, 120.0]).ok
    # the calibration setting itself: inside [min, max] of its repeats
    assert judge("latency_state_mean", 100.0, 125.0, 0.4, repeats=[90, 100, 130]).ok
    assert not judge("latency_state_mean", 100.0, 80.0, 0.4, repeats=[90, 100, 130]).ok
    # the rule is the mean metrics' only: p99 stays on the plain band
    assert judge("aoi_p99", 100.0, 125.0, floor=0.30) == Verdict(True, False, False, "band")
    assert judge("aoi_mean", math.nan, 1.0) == Verdict(False, False, False, "n/a")
    assert judge("aoi_mean", 0.0, 1.0) == Verdict(False, False, False, "n/a")
    # the DES delivered nothing where live did: a miss, not a cell left out
    assert judge("latency_state_mean", 5.0, math.nan) == Verdict(True, False, False,
                                                                 "no DES value")


def test_knee_of_is_capacitys_predicate_on_a_grid() -> None:
    ok = {"trigger_rate_hz": 100.0, "missed_frac": 0.0}
    figs = [ok, ok, {"trigger_rate_hz": 100.0, "missed_frac": 0.06}, ok]
    # 10, 20 hold; 30 misses 6 % > 5 %: capacity 20, knee 30 (60 holding again: noise)
    assert knee_of([10, 20, 30, 60], figs, 100.0) == (20, 30)
    slow = [ok, {"trigger_rate_hz": 94.0, "missed_frac": 0.0}, ok, ok]
    assert knee_of([10, 20, 30, 60], slow, 100.0) == (10, 20)  # rate not held at 20
    assert knee_of([10, 20], [ok, ok], 100.0) == (20, None)
    assert knee_of([10, 20], [{"trigger_rate_hz": math.nan, "missed_frac": 0.0}, ok],
                   100.0) == (None, 10)


def test_coverage_leave_one_out_by_hand() -> None:
    from sigma_lab.studies.validation.coverage import coverage_rows, residual_values

    def row(i: int, live: float, des: float, reg: str = "node-below") -> dict[str, object]:
        return {"held_out": True, "passed": True, "metric": "aoi_mean", "regime": reg,
                "live": live, "des": des, "rel_error": (des - live) / live, "cell": i}

    # residuals +10, -10, +20, -20, +5, +50 % in one regime; each cell's interval from
    # the other five (n = 5 < 9: their range, k = 0)
    errs = [0.1, -0.1, 0.2, -0.2, 0.05, 0.5]
    rows = [row(i, 10.0, 10.0 * (1 + e)) for i, e in enumerate(errs)]
    rows.append({**row(9, 10.0, 30.0), "held_out": False})  # in-sample: left out
    rows.append({**row(8, 10.0, 30.0), "passed": ""})  # not scored: left out
    (c,) = coverage_rows(rows, ["aoi_mean"])
    # covered iff its residual lies within the others' range: all but +50 % (others'
    # max +20 %) and -20 % (others' min -10 %)
    assert (c["cells"], c["covered"]) == (6, 4)
    assert c["share"] == pytest.approx(4 / 6)
    # the +10 % cell: others -20..+50 -> live in [11 / 1.5, 11 / 0.8]: width 0.7167
    a = 1 / 0.8 - 1 / 1.5
    widths = sorted([1.1 * a, 0.9 * a, 1.2 * a, 0.8 * (1 / 0.9 - 1 / 1.5), 1.05 * a,
                     1.5 * (1 / 0.8 - 1 / 1.2)])
    assert c["median_width"] == pytest.approx((widths[2] + widths[3]) / 2)
    vals = residual_values(rows)
    assert sorted(vals[("aoi_mean", "node-below")]) == pytest.approx(sorted(errs))
    assert vals[("aoi_mean", "any")] == vals[("aoi_mean", "node-below")]


def test_coverage_of_missed_frames_reaches_one_frame() -> None:
    from sigma_lab.studies.validation.coverage import coverage_rows

    def row(i: int, live: float, des: float) -> dict[str, object]:
        return {"held_out": True, "passed": True, "metric": "missed_frac",
                "regime": "node-below", "live": live, "des": des,
                "rel_error": 100 * (des - live), "cell": i}

    # nine cells miss nothing in either; the tenth's live lost a frame of 300 (the DES
    # none): the others' residuals are all 0, so only a frame's reach holds it
    rows = [row(i, 0.0, 0.0) for i in range(9)] + [row(9, 1 / 300, 0.0)]
    (bare,) = coverage_rows(rows, ["missed_frac"])
    (c,) = coverage_rows(rows, ["missed_frac"], frames=300.0)
    assert (bare["covered"], c["covered"]) == (9, 10)
    # each interval is [0, 1/300] (the lower reach clipped at 0): 1/3 pp wide; without
    # the frame, the tenth's is [0, 0] (the others' residuals all 0)
    assert c["median_width"] == pytest.approx(100 / 300)


def test_coverage_counts_the_rates_live_did_not_hold_in_their_regime() -> None:
    """Held rates (residual 0) and rates not held (live 60 Hz: unscored, read in
    ``node-limited``): the latter join the coverage and the residuals by their own
    regime; with a 3 s window a held rate's interval reaches 1/3 Hz."""
    from sigma_lab.studies.validation.coverage import coverage_rows, residual_values

    def row(i: int, live: float, des: float, reg: str, passed: object) -> dict[str, object]:
        return {"held_out": True, "passed": passed, "metric": "trigger_rate_hz",
                "regime": reg, "live": live, "des": des, "rel_error": (des - live) / live,
                "cell": i, "rule": "band" if passed != "" else "rate not held"}

    held = [row(i, 100.0, 100.0, "node-below", True) for i in range(4)]
    held.append(row(4, 99.7, 100.0, "node-below", True))  # one trigger short in 3 s
    limited = [row(5 + i, 60.0, 60.0 * (1 + e), "node-limited", "")
               for i, e in enumerate([-0.1, 0.05, -0.05, 0.1, 0.0])]
    (c,) = coverage_rows(held + limited, ["trigger_rate_hz"], window=3.0)
    assert c["cells"] == 10
    # the held 99.7 needs the trigger's reach (the others' residuals are all 0); each
    # limited cell lies within the other four's range but the two extremes (+-10 %)
    assert c["covered"] == 8
    (bare,) = coverage_rows(held + limited, ["trigger_rate_hz"])
    assert bare["covered"] == 7
    vals = residual_values(held + limited)
    assert sorted(vals[("trigger_rate_hz", "node-limited")]) == pytest.approx(
        [-0.1, -0.05, 0.0, 0.05, 0.1])


def test_judge_trigger_rate_only_where_live_holds_it() -> None:
    assert judge("trigger_rate_hz", 90.0, 90.0, f_trig=100.0) == Verdict(
        False, False, True, "rate not held")
    assert judge("trigger_rate_hz", 99.0, 95.0, f_trig=100.0).ok  # -4.0 %
    assert not judge("trigger_rate_hz", 99.0, 94.0, f_trig=100.0).ok  # -5.05 %
    assert judge("trigger_rate_hz", 48.0, 47.0, f_trig=50.0).ok


def test_judge_missed_frames_in_points() -> None:
    assert judge("missed_frac", 0.02, 0.12).ok  # 10 pp
    assert not judge("missed_frac", 0.02, 0.13).ok
    assert not judge("missed_frac", 0.50, 0.0).ok


def test_share_counts_scored_passed_and_band() -> None:
    vs = [Verdict(True, True, True, "band"), Verdict(True, True, False, "live range"),
          Verdict(True, False, False, "band"), Verdict(False, False, True, "rate not held")]
    assert share(vs) == (3, 2, 1)


def test_knee_smallest_n_above_five_percent() -> None:
    assert knee([10, 30, 60, 100], [0.0, 0.05, 0.2, 0.9]) == 60  # 5 % is not above
    assert knee([100, 10, 60, 30], [0.9, 0.0, 0.2, 0.06]) == 30  # any order
    assert knee([10, 30, 60], [0.0, 0.01, math.nan]) is None  # a failed run is skipped
    assert knee([10, 30, 60, 100], [0.0, 0.0, math.nan, 0.5]) == 100


def test_knee_verdict_within_a_quarter() -> None:
    assert knee_verdict(60, 45, 100) == "met"
    assert knee_verdict(60, 75, 100) == "met"
    assert knee_verdict(60, 44, 100) == "missed"
    assert knee_verdict(60, None, 100) == "missed"
    assert knee_verdict(None, None, 100) == "met"
    assert knee_verdict(None, 120, 100) == "met"  # both beyond live's grid
    assert knee_verdict(None, 80, 100) == "missed"


def test_hosts_for() -> None:
    assert [hosts_for(n) for n in (1, 10, 30, 50, 51, 60, 100, 150)] == [2, 2, 2, 2, 3, 3, 4, 6]
    with pytest.raises(ConfigError, match="nodes"):
        hosts_for(0)


def test_full_plan_cells_and_repeats_spread() -> None:
    one = [c.name for c in full_plan(("none", "bides"), cell_repeats=1).cells]
    assert len(one) == len(set(one)) == 15
    assert one[0] == "cal-r1" and one[-1] == "cal-r3"
    assert one.index("cal-r2") == 7  # after half of the 12 held-out cells
    plan = full_plan(("none", "bides"))  # every held-out cell twice by default
    names = [c.name for c in plan.cells]
    assert len(names) == len(set(names)) == 27
    # the copies are a second pass over the held-out grid, cal-r2 between the passes
    assert names[:13] == one[:7] + one[8:14]
    assert names[13] == "cal-r2" and names[-1] == "cal-r3"
    assert names[14:26] == [f"{n}-c2" for n in one[1:7] + one[8:14]]
    copy = plan.cells[14]
    assert (copy.name, copy.base, copy.copy, copy.held_out) == ("n10-node-c2", "n10-node", 2,
                                                                True)
    assert copy.live_sets() == plan.cells[1].live_sets()
    with pytest.raises(ConfigError, match="--cell-repeats"):
        full_plan(("none",), cell_repeats=0)
    assert {c.nodes for c in plan.cells if c.held_out and not c.impairment} == {10, 30, 60, 100}
    lat = next(c for c in plan.cells if c.name == "lat5-bundle")
    assert lat.live_sets() == ["nodes=30", "hosts=2", "net.host_link.latency.value=0.00525"]
    assert lat.des_sets() == ["nodes=30", "hosts=2"]  # bundle and +5 ms: prepare's options
    loss = next(c for c in plan.cells if c.name == "loss5-node")
    assert loss.des_sets() == ["nodes=30", "hosts=2", "net.host_link.loss.p=0.05"]


def test_select_keeps_the_calibration_run() -> None:
    plan = full_plan(("none",), cell_repeats=1).select("n30-*, lat5-node")
    assert [c.name for c in plan.cells] == ["cal-r1", "n30-node", "n30-bundle", "lat5-node"]
    plan = full_plan(("none",)).select("n30-node*")
    assert [c.name for c in plan.cells] == ["cal-r1", "n30-node", "n30-node-c2"]
    with pytest.raises(ConfigError, match="--grid"):
        full_plan(("none",)).select("n31-*")
    assert [c.name for c in quick_plan(("none",)).cells] == ["cal-r1", "n6-node", "n6-bundle",
                                                             "cal-r2"]


def test_a_bundled_calibration_run_is_neither_held_out_nor_a_repeat() -> None:
    plan = full_plan(("none",), cell_repeats=1, cal_bundle=True).select("n30-node")
    assert [c.name for c in plan.cells] == ["cal-r1", "cal-bundle", "n30-node",
                                            "cal-bundle-r2"]
    names = [c.name for c in full_plan(("none",), cal_bundle=True).cells]
    assert names.index("cal-bundle-r2") == names.index("cal-r2") + 1
    for cb in (plan.cells[1], plan.cells[3]):
        assert (cb.nodes, cb.mode, cb.repeat, cb.held_out, cb.cal_extra) == (
            40, "bundle", 0, False, True)
    # one repeat: one bundled run
    one = Plan(("none",), 4.0, 1.0, cal_nodes=4, nodes=(6,), extra_nodes=6, repeats=1,
               cal_bundle=True)
    assert [c.name for c in one.cells if c.cal_extra] == ["cal-bundle"]
    assert one.cells[1].nodes == 4  # cal_bundle_nodes 0: the calibration setting's N
    with pytest.raises(ConfigError, match="cal_bundle_nodes"):
        Plan(("none",), 4.0, 1.0, cal_nodes=4, nodes=(6,), extra_nodes=6, cal_bundle=True,
             cal_bundle_nodes=-1)
    # every scored cell differs from every calibration run in size
    assert all(c.nodes not in (20, 40) for c in full_plan(("none",), cal_bundle=True).cells
               if c.held_out)


def test_estimate_hand_computed() -> None:
    plan = Plan(("none",), 4.0, 1.0, cal_nodes=4, nodes=(6,), extra_nodes=6, repeats=1)
    # live: 7 cells x (4 + 1 x (4 + 1.6)); DES: 7 keys, 1 + 0.05 N each; calibration 40
    assert plan.estimate() == pytest.approx(7 * 9.6 + (1.2 + 6 * 1.3) + 40.0)
    with pytest.raises(ConfigError, match="--duration"):
        Plan(("none",), 1.0, 1.0, cal_nodes=4, nodes=(6,), extra_nodes=6)
