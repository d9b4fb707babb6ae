"""Smoke run of the A/B timing script: structure and a reproducible metrics digest (no timings)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "cpu_per_sim_s.py"
ARGS = ["--nodes", "10", "--duration", "0.3", "--method", "bides"]


def _run(*extra: str) -> str:
    return subprocess.run([sys.executable, str(SCRIPT), *ARGS, *extra], capture_output=True,
                          text=True, check=True, cwd=ROOT, timeout=300).stdout


def test_digest_is_reproducible_and_follows_the_scenario() -> None:
    pat = r"bides N=10 0.3 s: [0-9.]+ CPU-s/s; engine cohort; metrics ([0-9a-f]{12})"
    a, b = re.search(pat, _run()), re.search(pat, _run())
    c = re.search(pat, _run("--set", "seed=12345"))
    assert a and b and c
    assert a.group(1) == b.group(1) != c.group(1)
