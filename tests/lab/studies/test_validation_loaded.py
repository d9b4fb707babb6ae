"""The loaded-calibration check: the hog, the scores of both calibrations, the verdict."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import psutil
import pytest
from sigma_lab.studies.validation.grid import full_plan
from sigma_lab.studies.validation.loaded import (
    HOG,
    IDLE,
    Hog,
    loaded_md,
    loaded_rows,
    loaded_target,
    quietest,
)
from sigma_lab.studies.validation.scoring import METRICS

#: one held-out cell x method: live value and its two runs, per metric
LIVE = {"aoi_mean": (20.0, "19 21"), "aoi_p99": (30.0, "29 31"),
        "latency_state_mean": (2.0, "1.9 2.1"), "trigger_rate_hz": (100.0, "100 100"),
        "missed_frac": (0.0, "0 0")}
IDLE_DES = {"aoi_mean": 21.0, "aoi_p99": 40.0, "latency_state_mean": 2.2,
            "trigger_rate_hz": 100.0, "missed_frac": 0.02}  # +5 %, +33 %, +10 %, 0, 2 pp
HOG_DES = {"aoi_mean": 25.0, "aoi_p99": 31.0, "latency_state_mean": 3.0,
           "trigger_rate_hz": 90.0, "missed_frac": 0.2}  # +25 %, +3 %, +50 %, -10 %, 20 pp


RUN = {IDLE: "cal-r3", HOG: "cal-hog"}


def _rows() -> list[dict[str, Any]]:
    rows = [{"cell": "n30-node", "method": "none", "metric": k, "held_out": True, "live": v,
             "live_runs": runs, "noise_floor": 0.05} for k, (v, runs) in LIVE.items()]
    # a calibration run's own row: not held out, never scored here
    rows.append({**rows[0], "cell": "cal-r1", "held_out": False})
    return rows


def _calibration(out: Path, name: str, des: dict[str, float], background: float) -> None:
    d = out / "loaded" / name
    (d / "cal").mkdir(parents=True)
    (d / "des.json").write_text(json.dumps({"n30-node": {"none": des}}))
    (d / "cal" / "calibrated.json").write_text(json.dumps(
        {"background_cores_of_runs": {f"runs/{RUN[name]}": background}}))


def test_both_calibrations_scored_with_the_headline_rule(tmp_path: Path) -> None:
    _calibration(tmp_path, IDLE, IDLE_DES, 0.07)
    _calibration(tmp_path, HOG, HOG_DES, 1.05)
    got = {(r["calibration"], r["metric"]): r for r in
           loaded_rows(_rows(), tmp_path, cores=2, f_trig=100.0)}
    assert {k: got[(IDLE, k)]["within"] for k in METRICS} == {
        "aoi_mean": 1, "aoi_p99": 0, "latency_state_mean": 1, "trigger_rate_hz": 1,
        "missed_frac": 1}
    assert {k: got[(HOG, k)]["within"] for k in METRICS} == {
        "aoi_mean": 0, "aoi_p99": 1, "latency_state_mean": 0, "trigger_rate_hz": 0,
        "missed_frac": 0}
    assert all(r["scored"] == 1 for r in got.values())
    # 1.05 of 2 cores is above a quarter: predict refuses it; 0.07 is not
    assert got[(HOG, "aoi_mean")]["refused"] and not got[(IDLE, "aoi_mean")]["refused"]
    assert got[(HOG, "aoi_mean")]["background_cores"] == pytest.approx(1.05)
    assert got[(IDLE, "aoi_mean")]["run"] == "cal-r3"


def test_the_verdict(tmp_path: Path) -> None:
    assert loaded_rows(_rows(), tmp_path, cores=2, f_trig=100.0) == []  # nothing run
    _calibration(tmp_path, IDLE, IDLE_DES, 0.07)
    _calibration(tmp_path, HOG, HOG_DES, 1.05)
    refused = loaded_md(loaded_rows(_rows(), tmp_path, 2, 100.0), cores=2)
    assert refused[-1].startswith("- [x]") and "refused by `predict`" in refused[-1]
    assert ("| hog (`cal-hog`) | 1.05 | yes | 0 / 1 | 1 / 1 | 0 / 1 | 0 / 1 | 0 / 1 |"
            in "\n".join(refused))
    # the same predictions from a run at 0.3 cores (not refused): fewer cells -> not met
    (tmp_path / "loaded" / HOG / "cal" / "calibrated.json").write_text(json.dumps(
        {"background_cores_of_runs": {"runs/cal-hog": 0.3}}))  # (not refused)
    worse = loaded_md(loaded_rows(_rows(), tmp_path, 2, 100.0), cores=2)
    assert worse[-1].startswith("- [ ]") and "fewer cells" in worse[-1]
    # as good as the idle one on every metric -> met
    (tmp_path / "loaded" / HOG / "des.json").write_text(json.dumps(
        {"n30-node": {"none": IDLE_DES}}))
    good = loaded_md(loaded_rows(_rows(), tmp_path, 2, 100.0), cores=2)
    assert good[-1].startswith("- [x]") and "as many cells" in good[-1]
    idle_only = [r for r in loaded_rows(_rows(), tmp_path, 2, 100.0)
                 if r["calibration"] == IDLE]
    assert loaded_md(idle_only, cores=2) == [] and loaded_target(idle_only, 2) is None
    assert loaded_target(loaded_rows(_rows(), tmp_path, 2, 100.0), 2) == good[-1]


def test_the_hog_spins_a_core_and_is_bounded() -> None:
    with Hog(limit=30.0) as hog:
        assert hog.proc is not None
        used = 0.0
        for _ in range(100):  # at most ~10 s: a busy machine gives it a core late
            time.sleep(0.1)
            cpu = psutil.Process(hog.proc.pid).cpu_times()
            used = cpu.user + cpu.system
            if used > 0.3:
                break
        assert used > 0.3  # busy, not sleeping
    assert hog.proc.poll() is not None  # stopped with the block
    lone = Hog(limit=0.3)
    lone.__enter__()  # never exited: the spin loop ends by itself
    assert lone.proc is not None and lone.proc.wait(timeout=10) == 0


def test_the_idle_reference_is_the_quietest_repeat(tmp_path: Path) -> None:
    plan = full_plan(("none",))

    def run(name: str, cpu_s: list[float] | None) -> None:
        d = tmp_path / "live" / name
        d.mkdir(parents=True)
        cpu = [] if cpu_s is None else [
            {"process": "background", "window_s": 3.0, "cpu_s": c} for c in cpu_s]
        (d / "summary.json").write_text(json.dumps({"live": {"none": {"cpu": cpu}}}))

    run("cal-r1", [0.75])  # 0.25 cores
    run("cal-r2", [0.15, 0.45])  # 0.05 and 0.15: 0.10 cores, the quietest
    run("cal-r3", None)  # no figure: never chosen over one with it
    run("n30-node", [0.0])  # held out: not a repeat of the calibration setting
    assert quietest(plan, tmp_path) == "cal-r2"
    run("cal-bundle", [0.0])  # bundled: another setting
    assert quietest(plan, tmp_path) == "cal-r2"


def test_a_kept_idle_calibration_of_another_repeat_is_made_again(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The quietest repeat decides the idle reference: a kept calibration made on another
    repeat (an earlier choice) is redone with its predictions; the hog's is kept."""
    from sigma_lab.studies.validation import loaded
    from sigma_lab.studies.validation.grid import quick_plan

    plan = quick_plan(("none",))
    for name, cpu in (("cal-r1", 0.6), ("cal-r2", 0.0)):  # cal-r2 is the quieter now
        d = tmp_path / "live" / name
        d.mkdir(parents=True)
        (d / "summary.json").write_text(json.dumps({"live": {"none": {"cpu": [
            {"process": "background", "window_s": 3.0, "cpu_s": cpu}]}}}))
    hog_run = tmp_path / "loaded" / HOG / "cal-hog"
    hog_run.mkdir(parents=True)
    (hog_run / "summary.json").write_text("{}")
    for name, run in ((IDLE, "cal-r1"), (HOG, "cal-hog")):  # both kept from before
        _calibration(tmp_path, name, IDLE_DES, 0.1)
        (tmp_path / "loaded" / name / "cal" / "calibrated.json").write_text(json.dumps(
            {"background_cores_of_runs": {f"x/{run}": 0.1}}))
    made: list[str] = []

    def calibrate(runs: list[Path], cal_dir: Path, timeout: float) -> None:
        made.append(runs[0].name)
        (cal_dir / "calibrated.json").write_text(json.dumps(
            {"background_cores_of_runs": {str(runs[0]): 0.0}}))

    monkeypatch.setattr(loaded, "calibrate_run", calibrate)
    monkeypatch.setattr(loaded, "load_calibration", lambda d: (None, {}))
    monkeypatch.setattr(loaded, "des_cell", lambda cal, rep, cell, plan, d: {
        "methods": {"none": {k: 7.0 for k in METRICS}}})
    loaded.run_loaded(plan, tmp_path, say=lambda line: None)
    assert made == ["cal-r2"]  # the idle one again, on the quietest; the hog's kept
    idle = json.loads((tmp_path / "loaded" / IDLE / "des.json").read_text())
    assert set(idle) == {"n6-node", "n6-bundle"} and idle["n6-node"]["none"]["aoi_mean"] == 7.0
    hog = json.loads((tmp_path / "loaded" / HOG / "des.json").read_text())
    assert hog == {"n30-node": {"none": IDLE_DES}}  # untouched
