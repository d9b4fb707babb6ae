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
    _run("live_vs_des.py", tmp_path)
    rows = list(csv.DictReader((tmp_path / "comparison.csv").open()))
    assert {r["method"] for r in rows} == {"none", "bides"}
    assert {r["target"] for r in rows} == {"n6"}
    for r in rows:
        live, des, rel = float(r["live"]), float(r["des"]), float(r["rel_err"])
        if live:
            assert rel == pytest.approx((des - live) / live)
    cal = json.loads((tmp_path / "calibration.json").read_text())
    assert cal["hop_latency_mean_s"] > 0 and cal["delivery_service_s"] >= 0
    sc = load(str(tmp_path / "cal" / "calibrated.toml"))
    assert sc.payload_bits == 85 * 8 and sc.trigger_payload_bits == 33 * 8
    assert (tmp_path / "live_vs_des.png").stat().st_size > 1000
    assert (tmp_path / "live_n6" / "messages.csv.gz").exists()
