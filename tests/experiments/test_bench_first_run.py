"""Smoke run of the first-run cost script (structure only; timings are never asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "bench_first_run.py"


def test_quick_run_prints_three_steps_and_both_units() -> None:
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick"], capture_output=True,
                         text=True, check=True, cwd=ROOT, timeout=600).stdout
    steps = {}
    for ln in out.splitlines():
        for name in ("cold compare", "warmup --jobs 2", "compare after warm-up"):
            if ln.startswith(name):
                steps[name] = [float(x) for x in ln[len(name):].split()]
    assert set(steps) == {"cold compare", "warmup --jobs 2", "compare after warm-up"}
    assert all(len(v) == 2 and v[0] > 0 and v[1] > 0 for v in steps.values())
    units = [ln.split()[0] for ln in out.splitlines() if "kernels compiled" in ln]
    assert units == ["core", "physics"]
    assert "cold compile per kernel" in out


def test_bad_jobs_exits_2() -> None:
    r = subprocess.run([sys.executable, str(SCRIPT), "--jobs", "0"], capture_output=True,
                       text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 2 and "--jobs must be >= 1, got 0" in r.stderr
