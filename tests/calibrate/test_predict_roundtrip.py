"""A tiny live run -> ``calibrate`` -> ``predict`` / ``capacity`` round trip (bounded:
N = 4 on 2 hosts, one method, 1.5 s; skipped without Mosquitto)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from sigma_des.cli import main
from tests.live.live_helpers import needs_mosquitto

pytestmark = needs_mosquitto

SHORT = ["--set", "duration=1.5", "--set", "warmup=0.5"]


def test_live_calibrate_predict_capacity(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    assert main(["live", "--set", "nodes=4", "--set", "hosts=2", *SHORT, "--methods", "none",
                 "--out", str(run), "--no-plots", "--no-progress"]) == 0
    cal = tmp_path / "cal.toml"
    assert main(["calibrate", str(run), "--out", str(cal), "--no-check"]) == 0
    live = json.loads((run / "summary.json").read_text())["methods"]["none"]
    out = tmp_path / "p"
    # --allow-load: the suite's other workers load the machine during the live run
    assert main(["predict", str(cal), "--methods", "none", "--seeds", "2", "--out", str(out),
                 "--no-progress", "--allow-load"]) == 0
    pred = json.loads((out / "summary.json").read_text())
    assert (pred["nodes"], pred["hosts"], pred["seeds"]) == (4, 2, [live_seed(run),
                                                                  live_seed(run) + 1])
    aoi = pred["methods"]["none"]["aoi_mean"]
    assert aoi["lo"] <= aoi["mean"] <= aoi["hi"]
    assert math.isfinite(live["aoi_mean"])  # (how close depends on the machine's load)
    capsys.readouterr()
    assert main(["capacity", str(cal), "--methods", "none", "--n-min", "2", "--n-max", "8",
                 "--out", str(tmp_path / "c"), "--no-progress", "--allow-load"]) == 0
    assert "none" in capsys.readouterr().out
    row = next(csv.DictReader((tmp_path / "c" / "capacity.csv").open()))
    assert row["method"] == "none" and row["evaluated"]
    assert not math.isnan(float(row["capacity"] or "nan")) or row["first_failing"] == "2"


def live_seed(run: Path) -> int:
    """The live run's seed (the calibration keeps it)."""
    return int(json.loads((run / "summary.json").read_text())["seed"])
