"""The validation suite's run helpers and report, on hand-made inputs (no live runs)."""

from __future__ import annotations

import csv
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from sigma_lab.studies.validation.grid import Cell, Plan
from sigma_lab.studies.validation.knees import knee_rows
from sigma_lab.studies.validation.report import (
    cell_rows,
    noise_rows,
    under_load,
    write_outputs,
)
from sigma_lab.studies.validation.runs import (
    MissedTap,
    background_cores,
    bounded_run,
    calibrate_run,
    des_figures,
    shift_host_link,
)

from sigma_des.api import run_method
from sigma_des.calibrate.insample import missed_frac
from sigma_des.config import load
from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist, load_samples
from sigma_des.record import read_table


def test_missed_tap_hand_computed() -> None:
    tap = MissedTap(0.2, 0.7)
    for k in range(10):  # one trigger every 0.1 s: frames 2..6 leave in the window
        tap.issue(k, k * 0.1)
        tap.trigger(0, k, k * 0.1, k * 0.1 + 0.01)  # deliveries do not count again
    got = [(n, f) for f in range(1, 8) for n in (0, 1) if (n, f) != (1, 4)] + [(0, 3)]
    nodes = np.array([n for n, _ in got])
    frames = np.array([f for _, f in got])
    tap.states(np.zeros(len(got)), nodes, frames, np.zeros(len(got)), np.zeros((len(got), 12)))
    assert tap.missed_frac(2) == pytest.approx(1.0 - 9 / 10)  # (1, 4) never arrived
    assert math.isnan(MissedTap(5.0, 6.0).missed_frac(2))


def test_des_missed_frac_is_the_same_on_both_engines() -> None:
    """Both engines count the same frames, each trigger's issue (the per-message engine
    records deliveries, the compiled core issues): Lock-Step with a slow server process
    on one core and lossy links, where a frame's trigger reaches no node in time (was
    0.0 on the per-message engine, 0.5 on the compiled core; one third on both since the
    server's ticks wait for its loop thread, session 16)."""
    sc = load(None, ["nodes=6", "hosts=2", "duration=2", "warmup=0.5",
                     "fidelity.enabled=false", "net.host_link.loss.p=0.05",
                     'deployment.preset="colocated"', "deployment.cores=1",
                     "deployment.server_demand=0.004", "deployment.host_demand=0.001",
                     "deployment.lock_switch=0.005", 'deployment.clients="host"'])
    co = des_figures(sc, "lockstep")
    ev = des_figures(replace(sc, engine="events"), "lockstep")
    assert (co["engine"], ev["engine"]) == ("cohort", "events")
    assert co["missed_frac"] == ev["missed_frac"]
    assert co["missed_frac"] == pytest.approx(1 / 3)


def test_des_missed_frac_is_the_recordings(tmp_path: Path) -> None:
    """The tap's count equals the live runner's definition applied to an MCAP recording."""
    sc = load(None, ["nodes=4", "hosts=2", "duration=1.5", "warmup=0.5", "net.qos=0",
                     'net.transport="datagram"', "net.host_link.loss.p=0.2",
                     "fidelity.enabled=false"])
    figs = des_figures(sc, "none")
    run_method(sc, "none", record=tmp_path / "r.mcap")
    want = missed_frac(read_table(tmp_path / "r.mcap"), 4, 0.5, 1.5)
    assert 0.1 < want < 0.5
    assert figs["missed_frac"] == pytest.approx(want, abs=1e-12)


def test_shift_host_link_both_directions(tmp_path: Path) -> None:
    sc = load(None, [])
    shifted = shift_host_link(sc, 0.005, tmp_path)
    assert shifted.net.host_link.latency == Dist(dist="constant", value=0.00525)
    assert shifted.net.host_link.latency_down == Dist(dist="constant", value=0.00525)
    f = tmp_path / "hop.txt"
    f.write_text("0.001\n0.002\n")
    emp = Dist(dist="empirical", file=str(f))
    sc2 = load(None, [f'net.host_link.latency={{dist="empirical", file="{f}"}}'])
    assert sc2.net.host_link.latency == emp
    out = shift_host_link(sc2, 0.005, tmp_path / "s")
    assert np.allclose(load_samples(out.net.host_link.latency.file), [0.006, 0.007])
    assert np.allclose(load_samples(out.net.host_link.latency_down.file), [0.006, 0.007])
    assert out.net.server_link == sc2.net.server_link


def test_bounded_run_stops_a_hanging_process(tmp_path: Path) -> None:
    t0 = time.monotonic()
    status, timed_out = bounded_run([sys.executable, "-c", "import time; time.sleep(60)"],
                                    tmp_path / "log", 0.5)
    assert timed_out and status != 0
    assert time.monotonic() - t0 < 30
    status, timed_out = bounded_run([sys.executable, "-c", "print('hi')"], tmp_path / "log", 30)
    assert (status, timed_out) == (0, False)
    assert (tmp_path / "log").read_text() == "hi\n"


def test_background_cores_and_under_load() -> None:
    summ = {"live": {m: {"cpu": [{"process": "server", "cpu_s": 9.0, "window_s": 2.0},
                                 {"process": "background", "cpu_s": c, "window_s": 2.0}]}
                     for m, c in (("none", 0.4), ("bides", 1.2))}}
    assert background_cores(summ) == pytest.approx((0.2 + 0.6) / 2)
    assert math.isnan(background_cores({}))
    assert under_load({"background_cores": 0.6, "load_before": 0.0}, 2)
    assert not under_load({"background_cores": 0.4, "load_before": 9.0}, 2)
    assert under_load({"background_cores": math.nan, "load_before": 3.0}, 2)


def _live(missed: float, aoi: float, load: float = 1.0) -> dict[str, object]:
    m = {"aoi_mean": aoi, "aoi_p99": 2 * aoi, "latency_state_mean": 3.0,
         "trigger_rate_hz": 100.0, "missed_frac": missed}
    return {"methods": {"none": m}, "load_before": load, "load_after": load + 1.0,
            "background_cores": 0.1, "config_hash": "live0", "exit": 0, "timed_out": False}


def _des(missed: float, aoi: float) -> dict[str, object]:
    m = {"aoi_mean": aoi, "aoi_p99": 2 * aoi, "latency_state_mean": 3.3,
         "trigger_rate_hz": 100.0, "missed_frac": missed, "engine": "cohort", "fallback": ""}
    return {"methods": {"none": m}, "seed": 1, "config_hash": "des0", "version": "x"}


def test_rows_noise_floor_knee_and_outputs(tmp_path: Path) -> None:
    plan = Plan(("none",), 2.0, 0.5, cal_nodes=20, nodes=(10, 30), extra_nodes=30,
                repeats=2, knee_nodes=(10, 20, 30)).select("cal-r*,n10-node,n30-node")
    live = {"cal-r1": _live(0.0, 20.0), "cal-r2": _live(0.0, 30.0),
            "n10-node": _live(0.0, 10.0), "n30-node": _live(0.20, 40.0, load=5.0)}
    des = {"n20-node": _des(0.0, 22.0), "n10-node": _des(0.01, 13.0),
           "n30-node": _des(0.02, 48.0)}
    for n in (10, 20, 30):
        des.setdefault(f"n{n}-bundle", _des(0.0, 1.0))
    des["n20-node"]["methods"]["none"]["missed_frac"] = 0.08  # the DES's knee: 20
    outcome = (live, des, {"in_sample": [], "warnings": []})
    floor = {(r["method"], r["metric"]): r["noise_floor"] for r in noise_rows(plan, live)}
    assert floor[("none", "aoi_mean")] == pytest.approx(10.0 / 25.0)
    rows = cell_rows(plan, outcome, 100.0, cores=2)
    assert len(rows) == 3 * 5  # cal-r1 (in-sample) and two held-out cells; cal-r2 not a row
    r = {(x["cell"], x["metric"]): x for x in rows}
    assert r[("n10-node", "aoi_mean")]["rel_error"] == pytest.approx(0.3)
    # run once: the band alone, the calibration setting's 40 % floor is no licence
    assert r[("n10-node", "aoi_mean")]["passed"] is False  # +30 %
    assert r[("n10-node", "aoi_mean")]["rule"] == "band"
    assert r[("n30-node", "aoi_mean")]["passed"] is False  # +20 %
    assert r[("n10-node", "aoi_mean")]["regime"] == "node-near"  # DES missed 1 %
    assert r[("n30-node", "aoi_mean")]["regime"] == "node-near"
    assert r[("cal-r1", "aoi_mean")]["regime"] == "node-near"  # DES (n20) missed 8 %
    assert r[("n30-node", "missed_frac")]["rel_error"] == pytest.approx(-18.0)
    assert r[("n30-node", "missed_frac")]["passed"] is False
    assert r[("n30-node", "latency_state_mean")]["within_band"] is True  # +10 %
    assert r[("n30-node", "aoi_mean")]["load"] == 5.5
    assert r[("cal-r1", "aoi_mean")]["held_out"] is False
    assert r[("cal-r1", "aoi_mean")]["passed"] is True  # 22 inside the repeats' 20..30
    (k,) = knee_rows(plan, outcome, 100.0)
    assert (k["live_knee"], k["des_knee"], k["des_knee_on_live_grid"]) == (30, 20, 20)
    assert (k["live_capacity"], k["des_capacity"]) == (20, 10)
    assert k["live_grid"] == "10 20 30" and k["verdict"] == "missed"  # 20 is 33 % early
    write_outputs(plan, outcome, tmp_path, 100.0, "test")
    got = list(csv.DictReader((tmp_path / "cells.csv").open()))
    assert len(got) == 15 and got[0]["config_hash"] == "des0"
    md = (tmp_path / "summary.md").read_text()
    assert "| aoi_mean | ±15% | 2 | 0 (0 %) | 0 | ≥ 80% | ✘ |" in md
    assert "| latency_state_mean | ±15% | 2 | 2 (100 %) | 2 | ≥ 80% | ✔ |" in md
    assert "## Interval coverage" in md
    assert "**2 of 2 held-out cell x method pairs ran once**" in md
    cov = {r["metric"]: r for r in csv.DictReader((tmp_path / "coverage.csv").open())}
    assert cov["aoi_mean"]["cells"] == "2"  # each held-out cell, the other's residual
    assert "[[residual]]" in (tmp_path / "residuals.toml").read_text()
    assert "- [ ] knee within ±25 % (node messages)" in md
    assert "Not split: no calibration" in md  # a missed knee, no cal/: said, not skipped
    assert (tmp_path / "rounds.csv").exists()
    assert (tmp_path / "live_vs_des.png").stat().st_size > 10_000
    assert (tmp_path / "knee.png").stat().st_size > 10_000


def test_rows_of_a_cell_run_twice_and_the_fitted_repeat() -> None:
    """Copies: live is their mean, the floor their spread, the DES passes inside their
    range where they differ by more than 10 %; the in-sample row is the fitted repeat."""
    plan = Plan(("none",), 2.0, 0.5, cal_nodes=20, nodes=(10, 30), extra_nodes=30,
                repeats=2, cell_repeats=2).select("cal-r*,n10-node*,n30-node*")
    assert [c.name for c in plan.cells] == ["cal-r1", "n10-node", "n30-node", "n10-node-c2",
                                            "n30-node-c2", "cal-r2"]
    live = {"cal-r1": _live(0.0, 20.0), "cal-r2": _live(0.0, 30.0),
            "n10-node": _live(0.0, 10.0), "n10-node-c2": _live(0.0, 14.0, load=3.0),
            "n30-node": _live(0.0, 40.0)}  # n30's copy did not finish
    des = {"n20-node": _des(0.0, 29.0), "n10-node": _des(0.0, 13.5),
           "n30-node": _des(0.0, 50.0)}
    outcome = (live, des, {"in_sample": [], "warnings": [], "calibration_cell": "cal-r2"})
    rows = cell_rows(plan, outcome, 100.0, cores=2)
    r = {(x["cell"], x["metric"]): x for x in rows}
    assert {c for c, _ in r} == {"cal-r2", "n10-node", "n30-node"}  # no copy rows
    a = r[("n10-node", "aoi_mean")]
    assert a["live"] == pytest.approx(12.0) and a["live_runs"] == "10 14"
    assert a["noise_floor"] == pytest.approx(4.0 / 12.0) and a["floor_source"] == "cell"
    assert a["rel_error"] == pytest.approx(0.125) and a["rule"] == "band"
    assert a["load"] == pytest.approx((1 + 2 + 3 + 4) / 4)
    p99 = r[("n10-node", "aoi_p99")]  # 27 vs the mean 24: +12.5 %, inside the band
    assert p99["passed"] is True
    des["n10-node"]["methods"]["none"]["aoi_mean"] = 13.9  # +15.8 %, inside 10..14
    b = {(x["cell"], x["metric"]): x for x in cell_rows(plan, outcome, 100.0, cores=2)}
    assert b[("n10-node", "aoi_mean")]["rule"] == "live range"
    assert b[("n10-node", "aoi_mean")]["passed"] is True
    des["n10-node"]["methods"]["none"]["aoi_mean"] = 14.1  # outside the runs' range
    c = {(x["cell"], x["metric"]): x for x in cell_rows(plan, outcome, 100.0, cores=2)}
    assert c[("n10-node", "aoi_mean")]["passed"] is False
    one = r[("n30-node", "aoi_mean")]  # one run: the floor is shown, the band decides
    assert one["floor_source"] == "calibration"
    assert one["noise_floor"] == pytest.approx(10.0 / 25.0)
    assert one["passed"] is False and one["rule"] == "band"  # +25 %
    fit = r[("cal-r2", "aoi_mean")]
    assert fit["held_out"] is False and fit["live"] == 30.0 and fit["passed"] is True
    # a bundled calibration run (a campaign's) makes no row: it is neither scored nor
    # the in-sample row, which stays the fitted repeat
    plan_b = replace(plan, cells=(*plan.cells, Cell("cal-bundle", 20, "bundle",
                                                    cal_extra=True)))
    live["cal-bundle"] = _live(0.0, 18.0)
    des["n20-bundle"] = _des(0.0, 19.0)
    rb = cell_rows(plan_b, outcome, 100.0, cores=2)
    assert {x["cell"] for x in rb} == {"cal-r2", "n10-node", "n30-node"}


def test_calibrate_run_passes_its_extra_options_to_calibrate(tmp_path: Path) -> None:
    """``--calibrate-args`` reach ``sigma-des calibrate``: an option it does not know
    makes it exit 2 (argparse) before it reads the (empty) source, and the error names
    the exit and the log."""
    src = tmp_path / "live"
    src.mkdir()
    with pytest.raises(ConfigError, match=r"exited 2.*calibrate\.log"):
        calibrate_run(src, tmp_path / "cal", timeout=120.0, extra=["--no-such-option"])
    assert "--no-such-option" in (tmp_path / "cal" / "calibrate.log").read_text()
