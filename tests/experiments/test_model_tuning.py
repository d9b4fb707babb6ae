"""Smoke runs of experiments/model_tuning.py and bench_tuning.py (--quick); timings never
asserted. The report section must render the study's outputs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXP = ROOT / "experiments"


def test_model_tuning_quick_writes_outputs_and_report(tmp_path: Path) -> None:
    out = tmp_path / "model_tuning"
    subprocess.run([sys.executable, str(EXP / "model_tuning.py"), "--quick", "--out", str(out)],
                   check=True, capture_output=True, text=True, cwd=ROOT, timeout=600)
    s = json.loads((out / "summary.json").read_text())
    assert s["quick"] is True and set(s["identifiability"]) == {"quadrotor", "fixedwing"}
    for kind, runs in s["identifiability"].items():
        run = runs[0]
        assert (out / run["dir"] / "fitted.toml").exists()
        assert (out / run["dir"] / "fit_validation.png").exists()
        assert run["fitness_best"] <= run["fitness_start"], kind
        assert all("rel_error" in g for g in run["genes"])
    head = (out / "results.csv").read_text().splitlines()[0]
    assert head == "study,kind,seed,name,value,config_hash,version"
    sys.path.insert(0, str(EXP))
    try:
        import report_model_tuning
    finally:
        sys.path.remove(str(EXP))
    text = report_model_tuning.section(tmp_path)
    assert "0.93" in text and "quick mode" in text and "| quadrotor |" in text
    assert "Not run" in report_model_tuning.section(tmp_path / "none")


def test_bench_tuning_quick_prints_speedups() -> None:
    out = subprocess.run([sys.executable, str(EXP / "bench_tuning.py"), "--quick"],
                         check=True, capture_output=True, text=True, cwd=ROOT,
                         timeout=600).stdout
    rows = [ln.split() for ln in out.splitlines() if ln.split()[:1] in (["quadrotor"],
                                                                        ["fixedwing"])]
    assert len(rows) == 2
    assert all(float(r[-1]) > 0 and float(r[-2]) > 0 for r in rows)
    assert out.count("generations/s") == 2
