"""``experiments/interpolation.py --quick`` and ``bench_record.py`` at tiny scale."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXP = ROOT / "experiments"
METHODS = {"linear", "cubic", "pchip", "akima", "hermite-dw"}


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("interp")
    proc = subprocess.run([sys.executable, str(EXP / "interpolation.py"), "--quick", "--out",
                           str(d / "interpolation")], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return d


def test_outputs_and_table(out: Path) -> None:
    d = out / "interpolation"
    for f in ("results.csv", "summary.json", "trajectories.png", "error_vs_rate.png",
              "ablation.png"):
        assert (d / f).stat().st_size > 0, f
    with (d / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {r["method"] for r in rows} == METHODS | {"ablation"}
    assert {"seed", "version", "rate_hz", "noise", "window"} <= set(rows[0])
    s = json.loads((d / "summary.json").read_text())
    r = s["results"]["quadrotor"]["clean"]
    # noise-free logs: every method's error shrinks as the log rate grows
    for m in METHODS:
        errs = [r[str(x)][m]["mean"] for x in s["rates_hz"]]
        assert errs == sorted(errs, reverse=True), m
    for ac in s["aircraft"]:
        for nz in ("clean", "noisy"):
            for rate in s["rates_hz"]:
                e = s["results"][ac][nz][str(rate)]
                assert all(e[m]["max"] >= e[m]["rmse"] >= e[m]["mean"] > 0 for m in METHODS)


def test_report_section(out: Path) -> None:
    sys.path.insert(0, str(EXP))
    try:
        from report_interpolation import section
    finally:
        sys.path.remove(str(EXP))
    text = section(out)
    assert "| Akima | 0.609 / 4.089 / 0.993 |" in text and "quick mode" in text
    assert "Ablation of the window rule" in text
    assert "Not run: `python experiments/interpolation.py`" in section(out / "nothing")


def test_bench_record_tiny(tmp_path: Path) -> None:
    js = tmp_path / "b.json"
    proc = subprocess.run([sys.executable, str(EXP / "bench_record.py"), "--nodes", "4",
                           "--hosts", "2", "--duration", "0.5", "--dir", str(tmp_path),
                           "--out", str(js)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    b = json.loads(js.read_text())
    assert b["states"] == 4 * 50 and 0 < b["states_stored"] <= b["states"]
    assert b["bytes"]["incremental"] < b["bytes"]["full"]
    assert b["reconstruction"]["max_m"] < 0.1  # within the dead-band's reach
