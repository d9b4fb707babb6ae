"""Smoke run of the sequence benchmark (structure only; timings are never asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "bench_sequence.py"


def test_quick_sequence_prints_one_row_per_run() -> None:
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--methods", "none,bides"],
                         capture_output=True, text=True, check=True, cwd=ROOT,
                         timeout=300).stdout
    lines = out.splitlines()
    assert lines[0].startswith("N=10, 0.3 s simulated per run, methods none,bides in turn")
    rows = [ln.split() for ln in lines[2:5]]
    assert [r[:2] for r in rows] == [["0", "none"], ["1", "bides"], ["2", "none"]]
    # the same scenario and method give the same metric, whatever ran before
    assert rows[0][-1] == rows[2][-1]
    assert lines[5].startswith("median ")


def test_bad_runs_exits_2() -> None:
    r = subprocess.run([sys.executable, str(SCRIPT), "--nodes", "10", "--runs", "0"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2 and "--runs" in r.stderr
