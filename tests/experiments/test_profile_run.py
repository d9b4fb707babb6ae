"""Smoke run of the profile script (structure only; timings are never asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

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
