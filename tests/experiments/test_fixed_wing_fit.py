"""Smoke run of experiments/fixed_wing_fit.py --quick: every output is written, the GA
does not end worse than it started, and the table covers every log, parameter set and
channel, and the report section renders it. Timings are never asserted."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("jsbsim")

ROOT = Path(__file__).resolve().parents[2]


def test_fixed_wing_fit_quick(tmp_path: Path) -> None:
    out = tmp_path / "fixed_wing"
    r = subprocess.run([sys.executable, str(ROOT / "experiments" / "fixed_wing_fit.py"),
                        "--quick", "--out", str(out)], check=True, capture_output=True,
                       text=True, cwd=ROOT, timeout=600)
    assert "heldout_speed" in r.stdout
    s = json.loads((out / "summary.json").read_text())
    assert s["quick"] is True and [st["stage"] for st in s["tune"]["stages"]] == [
        "lateral", "longitudinal"]
    assert all(st["fitness_best"] <= st["fitness_start"] for st in s["tune"]["stages"])
    assert set(s["logs"]) == {"tuning", "heldout_inputs", "heldout_speed"}
    run = json.loads((out / "run.json").read_text())
    assert {"date", "machine", "load_before", "command", "wall_s", "cpu_s"} <= set(run)
    rows = list(csv.DictReader((out / "metrics.csv").open()))
    assert len(rows) == 3 * 3 * 5
    assert {r["channel"] for r in rows} == {"q", "p", "theta", "phi", "r"}
    genes = list(csv.DictReader((out / "genes.csv").open()))
    assert [g["name"] for g in genes][:2] == ["cll_p", "cll_da"]
    for name in ("fig15_heldout_inputs.png", "fig15_heldout_speed.png", "fitted.toml", "summary.md",
                 "tune/lateral/report.json", "tune/longitudinal/fitted.toml", "start.toml",
                 "tune_lateral.toml", "logs/tuning.csv", "logs/heldout_speed.csv"):
        assert (out / name).is_file(), name
    # the fitted file is complete: the glider's structure and the genes
    from sigma_des.agents.fitted import fitted_params

    p = fitted_params(out / "fitted.toml", "fixedwing")
    assert p.mass == pytest.approx(s["structure"]["mass"])
    assert p.aero.cm_q == pytest.approx(next(g["fitted"] for g in s["genes"]
                                             if g["name"] == "cm_q"))
    # the REPRODUCTION page's model-tuning section shows the held-out table
    sys.path.insert(0, str(ROOT / "experiments"))
    try:
        import report_model_tuning
    finally:
        sys.path.remove(str(ROOT / "experiments"))
    text = "\n".join(report_model_tuning._fixed_wing(tmp_path))
    assert "| heldout_speed | tuned |" in text and "0.073" in text
