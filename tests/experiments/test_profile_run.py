"""Smoke run of the profile script (structure only; timings are never asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "profile_run.py"


def test_quick_profile_lists_the_message_core() -> None:
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--top", "1000"],
                         capture_output=True, text=True, check=True, cwd=ROOT,
                         timeout=300).stdout
    assert "N=10 method=bides 0.3 s simulated" in out and "engine cohort" in out
    shares = [float(ln.split()[1].rstrip("%")) for ln in out.splitlines()[2:]]
    assert shares and all(0.0 <= s <= 100.0 for s in shares)
    assert "advance (loop.py" in out and " issue (trigger.py" in out


def test_bad_override_exits_2() -> None:
    r = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--set", "nodes=-1"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2 and "nodes" in r.stderr


def test_quick_phases_split_the_whole_path() -> None:
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--phases", "--top", "5"],
                         capture_output=True, text=True, check=True, cwd=ROOT,
                         timeout=300).stdout
    lines = out.splitlines()
    head = lines.index(next(ln for ln in lines if ln.startswith("phase ")))
    rows = {ln[:50].strip(): ln[50:].split() for ln in lines[head + 1 : head + 8]}
    assert list(rows) == [
        "set-up: scenario, dynamics, behaviour",
        "set-up: make_run (rings, network, tables, layout)",
        "run: the simulated seconds",
        "results: collector (finish)",
        "results: truth release",
        "results: fidelity (cached ideal run, DTW)",
        "results: tables (rows, table, summary)",
    ]
    # the warm-up loaded every kernel the timed path calls (load_kernels and a small
    # whole path): no phase loads or compiles one
    assert all(float(r[-1]) == 0 for r in rows.values())
    total = float(lines[head + 8].split()[1])
    # the rows are rounded to 0.1 ms
    assert total == pytest.approx(sum(float(r[0]) for r in rows.values()), abs=0.5)
    assert "N=10 method=bides 0.3 s whole path" in out
