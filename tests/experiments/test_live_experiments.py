"""experiments/bench_live.py and experiments/live_vs_des.py, smoke-run at tiny scale.

Both need Mosquitto (they run live); nothing here asserts on timing.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sigma_des.config import load
from sigma_des.live.broker import find_mosquitto
from sigma_des.live.wire import STATE_BYTES

#: the validation's scored metrics, in its tables' order
METRICS = ("aoi_mean", "aoi_p99", "latency_state_mean", "trigger_rate_hz", "missed_frac")

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(find_mosquitto() is None, reason="mosquitto is not installed")


def _run(script: str, out: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    subprocess.run([sys.executable, str(ROOT / "experiments" / script), "--quick", "--out",
                    str(out)], check=True, env=env, timeout=300, capture_output=True)


def test_bench_live_quick(tmp_path: Path) -> None:
    _run("bench_live.py", tmp_path)
    rows = list(csv.DictReader((tmp_path / "bench_live.csv").open()))
    assert [(r["mode"], r["method"]) for r in rows] == [("bundle", "bides")]
    for r in rows:
        assert 0.0 <= float(r["missed_frac"]) <= 1.0
        assert float(r["latency_state_mean"]) > 0
        assert r["meets_goal"] == "False"  # N = 4 is below the goal's 100 nodes


def test_live_vs_des_quick(tmp_path: Path) -> None:
    """The validation suite's smoke run, then a rerun that keeps every finished cell."""
    if not hasattr(load(None, []), "deployment"):
        pytest.skip("the bundled cells need the deployment keys (cpu branch)")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, str(ROOT / "experiments" / "live_vs_des.py"), "--quick", "--out",
           str(tmp_path)]
    first = subprocess.run(cmd, check=True, env=env, timeout=600, capture_output=True, text=True)
    assert "expected wall time" in first.stderr
    # the kernels compiled before the first live run (a cold cache stalls it)
    assert "compiling the numba kernels first" in first.stderr
    assert "warm-up done" in (tmp_path / "warmup.log").read_text()
    rows = list(csv.DictReader((tmp_path / "cells.csv").open()))
    assert {r["cell"] for r in rows} == {"cal-r1", "n6-node", "n6-bundle"}
    assert {r["method"] for r in rows} == {"none", "bides"}
    assert len(rows) == 3 * 2 * 5
    for r in rows:
        live, des, err = float(r["live"]), float(r["des"]), float(r["rel_error"])
        if r["metric"] == "missed_frac":
            assert err == pytest.approx(100 * (des - live))
        elif live:
            assert err == pytest.approx((des - live) / live)
        assert r["held_out"] == str(r["cell"] != "cal-r1")
        assert float(r["load"]) >= 0 and r["under_load"] in ("True", "False")
    noise = list(csv.DictReader((tmp_path / "noise.csv").open()))
    assert len(noise) == 2 * 5 and all(len(n["repeats"].split()) == 2 for n in noise)
    knees = list(csv.DictReader((tmp_path / "knee.csv").open()))
    assert {(k["mode"], k["method"]) for k in knees} == {
        (m, x) for m in ("node", "bundle") for x in ("none", "bides")}
    des = json.loads((tmp_path / "cells" / "des-n6-bundle.json").read_text())
    assert set(des["methods"]) == {"none", "bides"}
    assert "## Targets" in (tmp_path / "summary.md").read_text()
    assert (tmp_path / "live_vs_des.png").stat().st_size > 10_000
    sc = load(str(tmp_path / "cal" / "calibrated.toml"))
    assert sc.payload_bits == STATE_BYTES * 8 == 93 * 8 and sc.nodes == 4
    assert (tmp_path / "live" / "cal-r1" / "messages.csv.gz").exists()
    # the rerun adds the loaded check: a run beside a CPU hog, two one-run calibrations
    again = subprocess.run([*cmd, "--loaded-check"], check=True, env=env, timeout=900,
                           capture_output=True, text=True)
    kept = [ln for ln in again.stderr.splitlines() if ln.startswith("[") and "kept" in ln]
    assert len(kept) == 4  # every live cell
    assert "calibration: kept" in again.stderr
    loaded = list(csv.DictReader((tmp_path / "loaded.csv").open()))
    assert [(r["calibration"], r["metric"]) for r in loaded] == [
        (c, k) for c in ("idle", "hog") for k in METRICS]
    rows = list(csv.DictReader((tmp_path / "cells.csv").open()))
    held = {k: sum(r["metric"] == k and r["held_out"] == "True" and r["passed"] != ""
                   for r in rows) for k in METRICS}
    assert all(int(r["scored"]) == held[r["metric"]] for r in loaded)
    hog = next(r for r in loaded if r["calibration"] == "hog")
    assert float(hog["background_cores"]) > 0.5  # a core kept busy beside the run
    text = (tmp_path / "summary.md").read_text()
    assert "## A calibration under load" in text
    targets = text.split("## Targets")[1].split("\n## ")[0]  # ticked in the target list too
    assert "a calibration under load is refused, or predicts as well" in targets
    assert list(csv.DictReader((tmp_path / "cells.csv").open())) == rows
    # calibrate's own options: the kept live cells stay, the calibration is redone with them
    third = subprocess.run([*cmd, "--calibrate-args=--one-thread"], check=True, env=env,
                           timeout=600, capture_output=True, text=True)
    assert "calibration: kept" not in third.stderr and "calibrating on" in third.stderr
    assert json.loads((tmp_path / "cal" / "source.json").read_text())["args"] == ["--one-thread"]
