"""Live's knee runs: above the held-out grid, per mode, while a method still holds at
the largest size live ran; they enter the knee table, not the held-out shares."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from sigma_lab.studies.validation import suite
from sigma_lab.studies.validation.grid import Cell, Plan, full_plan, quick_plan
from sigma_lab.studies.validation.knees import knee_rows, run_knees
from sigma_lab.studies.validation.suite import holding

from sigma_des.errors import ConfigError

METHODS = ("none", "bides")


def _plan(knee_live: tuple[int, ...] = (120, 150)) -> Plan:
    return Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60, 100), extra_nodes=30, repeats=1,
                knee_nodes=(60, 100, 120, 150), knee_live=knee_live)


def _run(rates: dict[str, float], missed: dict[str, float]) -> dict[str, Any]:
    return {"methods": {m: {"trigger_rate_hz": rates[m], "missed_frac": missed[m]}
                        for m in METHODS},
            "background_cores": 0.0, "load_before": 0.0, "load_after": 0.0,
            "timed_out": False, "exit": 0, "wall_s": 1.0}


HOLD = {"none": 100.0, "bides": 100.0}


def test_knee_live_sizes_must_increase_above_the_held_out_grid() -> None:
    for bad in ((100,), (150, 120), (120, 120)):
        with pytest.raises(ConfigError, match="knee_live"):
            _plan(bad)
    assert full_plan(("none",)).knee_live == (120, 150, 180)
    assert quick_plan(("none",)).knee_live == ()
    assert [c.name for c in _plan().knee_live_cells("node")] == ["knee-n120-node",
                                                                "knee-n150-node"]


def test_holding_at_the_largest_size_live_ran() -> None:
    """Two runs at N = 100: bides holds in both (rate 100 %, missed 3 %); none's mean
    missed is 6 % (4 and 8): over the 5 % budget. With a knee run at 120 where bides
    drops to 76 Hz, nothing holds at the top any more."""
    live = {"n100-node": _run(HOLD, {"none": 0.04, "bides": 0.03}),
            "n100-node-c2": _run(HOLD, {"none": 0.08, "bides": 0.03}),
            "n60-node": _run(HOLD, {"none": 0.0, "bides": 0.0})}
    plan = Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60, 100), extra_nodes=30,
                repeats=1, knee_nodes=(120,), knee_live=(120, 150), cell_repeats=2)
    assert holding(plan, live, "node", 100.0) == ["bides"]
    live["knee-n120-node"] = _run({"none": 100.0, "bides": 76.3},
                                  {"none": 0.25, "bides": 0.051})
    assert holding(plan, live, "node", 100.0) == []
    assert holding(plan, live, "bundle", 100.0) == []  # nothing ran bundled


def test_knee_runs_stop_when_nothing_holds(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Per node bides holds at 100 -> live runs 120, where it fails -> no 150. Bundled
    both hold at 100 and at 120 -> 150 runs too, and the list ends there."""
    ran: list[str] = []
    figures = {"knee-n120-node": _run({"none": 60.0, "bides": 70.0}, {"none": 0.3, "bides": 0.1}),
               "knee-n120-bundle": _run(HOLD, {"none": 0.0, "bides": 0.0}),
               "knee-n150-bundle": _run({"none": 100.0, "bides": 90.0},
                                        {"none": 0.0, "bides": 0.2})}

    def fake_live_cell(cell: Cell, plan: Plan, out: Path) -> dict[str, Any]:
        ran.append(cell.name)
        out.mkdir(parents=True)
        (out / "summary.json").write_text("{}")
        return figures[cell.name]

    monkeypatch.setattr(suite, "live_cell", fake_live_cell)
    (tmp_path / "cells").mkdir()
    plan = _plan()
    live = {"n60-node": _run(HOLD, {"none": 0.0, "bides": 0.0}),
            "n100-node": _run({"none": 80.0, "bides": 100.0}, {"none": 0.2, "bides": 0.0}),
            "n60-bundle": _run(HOLD, {"none": 0.0, "bides": 0.0}),
            "n100-bundle": _run(HOLD, {"none": 0.0, "bides": 0.0})}
    said: list[str] = []
    suite._knee_live(plan, live, tmp_path, said.append)
    assert ran == ["knee-n120-node", "knee-n120-bundle", "knee-n150-bundle"]
    assert json.loads((tmp_path / "cells" / "knee-n120-node.live.json").read_text())[
        "methods"]["bides"]["trigger_rate_hz"] == 70.0
    # resumed: every run kept, nothing runs again
    suite._knee_live(plan, live, tmp_path, said.append)
    assert len(ran) == 3
    # the knee table reads them: per node bides' knee is 120 on live's grid
    des = {f"n{n}-{m}": {"methods": {k: {"trigger_rate_hz": 100.0, "missed_frac": 0.0}
                                     for k in METHODS}} for n in (60, 100, 120, 150)
           for m in ("node", "bundle")}
    rows = {(r["mode"], r["method"]): r for r in knee_rows(plan, (live, des, {}))}
    assert rows[("node", "bides")]["live_grid"] == "60 100 120"
    assert rows[("node", "bides")]["live_knee"] == 120
    assert rows[("node", "none")]["live_knee"] == 100
    assert rows[("bundle", "bides")]["live_grid"] == "60 100 120 150"
    assert rows[("bundle", "bides")]["live_knee"] == 150
    assert rows[("bundle", "none")]["live_knee"] is None


def test_bundled_calibration_runs_are_one_knee_point_the_mean_of_their_runs() -> None:
    """Two bundled calibration runs at N = 40: live's bundled grid holds 40 once, and
    its figures are the two runs' mean (missed 4 % and 8 %: 6 %, beyond the 5 % budget,
    so the knee is 40 though the first run alone holds)."""
    plan = Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60, 100), extra_nodes=30,
                repeats=2, knee_nodes=(40, 60, 100), cal_bundle=True, cal_bundle_nodes=40)
    ok = _run(HOLD, {"none": 0.0, "bides": 0.0})
    live = {"cal-r1": ok, "cal-r2": ok, "n60-bundle": ok, "n100-bundle": ok,
            "cal-bundle": _run(HOLD, {"none": 0.04, "bides": 0.0}),
            "cal-bundle-r2": _run(HOLD, {"none": 0.08, "bides": 0.0})}
    des = {f"n{n}-bundle": {"methods": {k: {"trigger_rate_hz": 100.0, "missed_frac": 0.0}
                                        for k in METHODS}} for n in (40, 60, 100)}
    rows = {(r["mode"], r["method"]): r for r in knee_rows(plan, (live, des, {}))}
    assert rows[("bundle", "none")]["live_grid"] == "40 60 100"
    assert rows[("bundle", "none")]["live_knee"] == 40
    assert rows[("bundle", "bides")]["live_knee"] is None
    # each repeat on its own: the first holds at 40 (4 %) and everywhere after, the
    # second not (8 %); the DES holds everywhere: missed against the mean's knee, but
    # the knee of the first repeat
    none = rows[("bundle", "none")]
    assert none["live_run_knees"] == "- 40" and none["verdict"] == "missed"
    assert none["within_a_live_run"] is True
    assert rows[("bundle", "bides")]["live_run_knees"] == "- -"


def test_run_knees_take_each_sizes_jth_run_or_its_last() -> None:
    """Sizes 10, 20, 30: 10 run twice (both hold), 20 twice (the second fails), 30 once
    (fails): repeat 1's knee 30, repeat 2's 20."""
    def run(rate: float) -> dict[str, object]:
        return {"methods": {"none": {"trigger_rate_hz": rate, "missed_frac": 0.0}}}

    runs = [[run(100.0), run(99.0)], [run(98.0), run(90.0)], [run(80.0)]]
    assert run_knees([10, 20, 30], runs, "none", 100.0) == [30, 20]
    assert run_knees([10, 20, 30], [], "none", 100.0) == []


def test_a_size_whose_runs_disagree_about_holding_runs_once_more(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """N = 60 per node: bides holds in one run (97 Hz) and not in the other (93 Hz), none
    in both: one tie-break run ``n60-node-c3`` (bides 94 Hz); the cell's live value is
    the mean of its three runs and live's knee follows it (95 % of 100 Hz needed: the
    mean 94.67 does not hold). N = 100, which no method holds in either run, and the
    bundled sizes, which agree, run nothing more; a second pass keeps the run."""
    ran: list[str] = []

    def fake_live_cell(cell: Cell, plan: Plan, out: Path) -> dict[str, Any]:
        ran.append(cell.name)
        out.mkdir(parents=True)
        (out / "summary.json").write_text("{}")
        return _run({"none": 100.0, "bides": 94.0}, {"none": 0.0, "bides": 0.0})

    monkeypatch.setattr(suite, "live_cell", fake_live_cell)
    (tmp_path / "cells").mkdir()
    plan = Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60, 100), extra_nodes=30, repeats=1,
                knee_nodes=(60, 100), cell_repeats=2, knee_tiebreak=1)
    assert [c.name for c in plan.tiebreak_cells(Cell("n60-node", 60))] == ["n60-node-c3"]
    fail = _run({"none": 80.0, "bides": 80.0}, {"none": 0.0, "bides": 0.0})
    live = {"n60-node": _run({"none": 100.0, "bides": 97.0}, {"none": 0.0, "bides": 0.0}),
            "n60-node-c2": _run({"none": 100.0, "bides": 93.0}, {"none": 0.0, "bides": 0.0}),
            "n100-node": fail, "n100-node-c2": fail,
            "n60-bundle": _run(HOLD, {"none": 0.0, "bides": 0.0}),
            "n60-bundle-c2": _run(HOLD, {"none": 0.0, "bides": 0.0})}
    said: list[str] = []
    suite._knee_tiebreak(plan, live, tmp_path, said.append)
    assert ran == ["n60-node-c3"]
    assert any("disagree about holding (bides): n60-node-c3" in s for s in said)
    suite._knee_tiebreak(plan, live, tmp_path, said.append)  # three runs: still split,
    assert ran == ["n60-node-c3"]  # but the tie-break run is kept, not run again
    des = {f"n{n}-{m}": {"methods": {k: {"trigger_rate_hz": 100.0, "missed_frac": 0.0}
                                     for k in METHODS}} for n in (60, 100)
           for m in ("node", "bundle")}
    rows = {(r["mode"], r["method"]): r for r in knee_rows(plan, (live, des, {}))}
    assert rows[("node", "bides")]["live_knee"] == 60  # (97 + 93 + 94) / 3 = 94.67
    assert rows[("node", "bides")]["live_run_knees"] == "100 60 60"
    assert rows[("node", "none")]["live_knee"] == 100
    with pytest.raises(ConfigError, match="--knee-tiebreak"):
        Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60,), extra_nodes=30, knee_tiebreak=4)
    assert full_plan(("none",)).knee_tiebreak == 1 and quick_plan(("none",)).knee_tiebreak == 0


def test_the_calibration_reads_every_repeat_the_most_typical_first(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Three repeats (mean AoI 20, 30, 21 ms: the typical one is cal-r3) and a bundled
    run: `sigma-des calibrate` gets cal-r3, cal-r1, cal-r2, then cal-bundle; the same
    runs again keep the calibration."""
    got: list[list[str]] = []

    def fake_calibrate(runs: list[Path], cal: Path, extra: Any = ()) -> None:
        got.append([p.name for p in runs])
        cal.mkdir(parents=True, exist_ok=True)
        (cal / "calibrated.toml").write_text("")
        (cal / "calibrated.json").write_text("{}")

    monkeypatch.setattr(suite, "calibrate_run", fake_calibrate)
    plan = Plan(METHODS, 4.0, 1.0, cal_nodes=20, nodes=(60,), extra_nodes=30, repeats=3,
                cal_bundle=True, cal_bundle_nodes=40)

    def rep(aoi: float) -> dict[str, Any]:
        r = _run(HOLD, {"none": 0.0, "bides": 0.0})
        for m in METHODS:
            r["methods"][m].update(aoi_mean=aoi, latency_state_mean=2.0)
        return r

    live = {"cal-r1": rep(20.0), "cal-r2": rep(30.0), "cal-r3": rep(21.0),
            "cal-bundle": rep(25.0)}
    for name in live:
        (tmp_path / "live" / name).mkdir(parents=True)
        (tmp_path / "live" / name / "summary.json").write_text("{}")
    suite._calibration(plan, live, tmp_path, lambda s: None, [])
    assert got == [["cal-r3", "cal-r1", "cal-r2", "cal-bundle"]]
    suite._calibration(plan, live, tmp_path, lambda s: None, [])
    assert len(got) == 1  # kept
