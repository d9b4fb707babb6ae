"""``sigma-des predict`` and ``capacity`` on a synthetic calibration: bad input refused
naming the option (exit 2), the outputs consistent with the interval rule, the target
prepared by the same function as the validation suite's."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from sigma_des.calibrate.campaign import loaded_runs
from sigma_des.calibrate.capacity import holds
from sigma_des.calibrate.intervals import interval, load_residuals, lookup, rate_regime
from sigma_des.calibrate.predict import load_calibration
from sigma_des.calibrate.target import prepare
from sigma_des.cli import main
from sigma_des.config import config_hash
from tests.calibrate.test_calibrate_cpu import _cpu_run

SHORT = ["--set", "duration=0.6", "--set", "warmup=0.2", "--no-progress"]


@pytest.fixture(scope="module")
def cal(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("cal")
    run = _cpu_run(d / "run")
    assert main(["calibrate", str(run), "--out", str(d / "cal.toml"), "--no-check",
                 "--no-match"]) == 0
    return d / "cal.toml"


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    return err[0]


def test_bad_input_is_refused_naming_the_option(cal: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    c = str(cal)
    assert "nodez" in _refused(["predict", c, "--set", "nodez=3"], capsys)
    lone = tmp_path / "lone.toml"
    lone.write_text(cal.read_text())
    assert "CAL" in _refused(["predict", str(lone)], capsys)
    assert "report" in _refused(["predict", str(lone)], capsys)
    assert "--seeds" in _refused(["predict", c, "--seeds", "0"], capsys)
    assert "--add-latency" in _refused(["predict", c, "--add-latency", "-1"], capsys)
    assert "--methods" in _refused(["predict", c, "--methods", "none,foo"], capsys)
    assert "--max-missed" in _refused(["capacity", c, "--max-missed", "1.5"], capsys)
    assert "--max-latency" in _refused(["capacity", c, "--max-latency", "0"], capsys)
    assert "--hosts-rule" in _refused(["capacity", c, "--hosts-rule", "per=0"], capsys)
    assert "--set" in _refused(["capacity", c, "--set", "nodes=9"], capsys)
    assert "--n-min" in _refused(["capacity", c, "--n-min", "50", "--n-max", "10"], capsys)


def test_a_calibration_under_load_is_refused(cal: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """A run whose background was above 25 % of the cores makes predict and capacity exit
    2 naming --allow-load and the run; at exactly 25 % it is not under load."""
    busy = tmp_path / "busy.toml"
    busy.write_text(cal.read_text())
    report = json.loads(cal.with_suffix(".json").read_text())
    cores = load_calibration(cal)[0].deployment.cores
    report["background_cores_of_runs"] = {"runs/a": 0.25 * cores, "runs/b": 0.26 * cores}
    busy.with_suffix(".json").write_text(json.dumps(report))
    assert loaded_runs(report, cores) == {"runs/b": 0.26 * cores}
    for cmd in ("predict", "capacity"):
        err = _refused([cmd, str(busy), "--methods", "none"], capsys)
        assert "--allow-load" in err and "runs/b" in err and "runs/a" not in err
    # with --allow-load the next check (an --out that is a file) speaks: it got through
    assert "--out" in _refused(["predict", str(busy), "--methods", "none", "--allow-load",
                                "--out", str(busy)], capsys)


def test_predict_is_the_suites_preparation(cal: Path, tmp_path: Path) -> None:
    from sigma_lab.studies.validation.grid import Cell, quick_plan
    from sigma_lab.studies.validation.runs import des_scenario

    sc, rep = load_calibration(cal)
    plan = quick_plan(("none",))
    for cell in (Cell("n6-bundle", 6, "bundle"), Cell("lat5-node", 6, "node", "lat5")):
        lab = des_scenario(sc, rep, cell, plan, tmp_path / "lab")
        ours = prepare(sc, rep, [f"nodes={cell.nodes}", f"hosts={cell.hosts}",
                                 f"duration={plan.duration}", f"warmup={plan.warmup}"],
                       bundle=cell.mode == "bundle",
                       add_latency_s=0.005 if cell.impairment else 0.0,
                       samples_dir=tmp_path / "lab")  # the shifted files: same path
        assert config_hash(lab) == config_hash(ours)


def test_predict_writes_results_and_intervals(cal: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "p"
    assert main(["predict", str(cal), "--set", "nodes=4", "--seeds", "2", "--methods", "none",
                 "--out", str(out), *SHORT]) == 0
    text = capsys.readouterr().out
    assert "node-" in text and "aoi_mean" in text
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [(r["seed"], r["metric"]) for r in rows][:2] == [("3", "aoi_mean"), ("3", "aoi_p99")]
    assert len(rows) == 2 * 5
    summ = json.loads((out / "summary.json").read_text())
    # the calibration run here is bundled; without --bundle the prediction is per node
    assert summ["state_hop_rule"].startswith("per node; the host's burst")
    assert f"state hops x{summ['state_hop_factor']:.3g}" in text
    table, meta = load_residuals()
    m = summ["methods"]["none"]
    for k in ("aoi_mean", "latency_state_mean", "missed_frac"):
        vals = [float(r["value"]) for r in rows if r["metric"] == k]
        # at the coverage the residuals file was written for, as predict builds them (a
        # missed-frame interval reaching at least one frame of the 0.4 s window: 40)
        iv = interval(k, vals, lookup(table, k, m["regime"]), float(meta["coverage"]),
                      frames=40.0, window=0.4, f_trig=100.0)
        assert (m[k]["mean"], m[k]["lo"], m[k]["hi"]) == pytest.approx((iv.mean, iv.lo, iv.hi))
        assert m[k]["residual"]["source"]
    # the trigger rate: read in its own regime, one trigger of the 0.4 s window either
    # side at least, never above the nominal 100 Hz
    vals = [float(r["value"]) for r in rows if r["metric"] == "trigger_rate_hz"]
    assert m["rate_regime"] == rate_regime(m["regime"], sum(vals) / len(vals), 100.0)
    iv = interval("trigger_rate_hz", vals, lookup(table, "trigger_rate_hz", m["rate_regime"]),
                  float(meta["coverage"]), window=0.4, f_trig=100.0)
    got = m["trigger_rate_hz"]
    assert (got["lo"], got["hi"]) == pytest.approx((iv.lo, iv.hi))
    assert got["lo"] <= got["mean"] - 2.5 + 1e-9 and got["hi"] <= max(100.0, got["mean"])


@pytest.mark.parametrize("f_trig", [None, 50.0])
def test_capacity_small_search(cal: Path, tmp_path: Path, f_trig: float | None,
                               capsys: pytest.CaptureFixture[str]) -> None:
    """The capacity is the largest evaluated N that holds; a target's own trigger rate
    (``--set f_trig=50``) is the rate it must hold, not the calibration's."""
    out = tmp_path / "c"
    extra = [] if f_trig is None else ["--set", f"f_trig={f_trig}"]
    assert main(["capacity", str(cal), "--methods", "none", "--n-min", "2", "--n-max", "8",
                 "--hosts-rule", "per=2", "--max-latency", "50", "--out", str(out),
                 *SHORT, *extra]) == 0
    nominal = load_calibration(cal)[0].f_trig if f_trig is None else f_trig
    assert json.loads((out / "summary.json").read_text())["f_trig_hz"] == nominal
    assert "capacity" in capsys.readouterr().out
    caps = list(csv.DictReader((out / "capacity.csv").open()))
    assert caps[0]["method"] == "none"
    pts = list(csv.DictReader((out / "points.csv").open()))
    means = {(int(r["nodes"]), r["metric"]): float(r["mean"]) for r in pts}
    cap = int(caps[0]["capacity"]) if caps[0]["capacity"] else 0
    for n in {n for n, _ in means}:  # the capacity is the largest evaluated N that holds
        ok = holds(means[(n, "trigger_rate_hz")], means[(n, "missed_frac")],
                   means[(n, "latency_state_mean")], nominal, 0.05, 50.0)
        assert ok == (n <= cap), n
    if f_trig is not None:  # the runs held the target's rate, so it is not "never held"
        assert cap >= 2 and means[(2, "trigger_rate_hz")] == pytest.approx(f_trig, rel=0.05)
    assert (out / "capacity.png").stat().st_size > 0
