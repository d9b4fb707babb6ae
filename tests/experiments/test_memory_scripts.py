"""Smoke runs of the memory scripts (structure and exit codes; sizes are never asserted)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXP = ROOT / "experiments"


def test_profile_memory_quick_reports_snapshots() -> None:
    r = subprocess.run([sys.executable, str(EXP / "profile_memory.py"), "--quick"],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "N=10" in r.stdout and "MB" in r.stdout


def test_tree_rss_counts_the_child_and_passes_its_exit_status() -> None:
    child = "import sys; b = bytearray(40 * 2**20); import time; time.sleep(0.6); sys.exit(3)"
    r = subprocess.run([sys.executable, str(EXP / "tree_rss.py"), "--interval", "0.05", "--",
                        sys.executable, "-c", child],
                       capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 3
    m = re.search(r"per-process peak RSS MB: \d+ \(parent\) (\d+)", r.stderr)
    assert m is not None, r.stderr
    assert int(m.group(1)) >= 40  # the 40 MB the child touched are in its peak


def test_tree_rss_without_a_command_is_an_error() -> None:
    r = subprocess.run([sys.executable, str(EXP / "tree_rss.py")],
                       capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 2 and "no command" in r.stderr


def test_bench_memory_quick_prints_a_row_per_method_and_the_core_arrays() -> None:
    r = subprocess.run([sys.executable, str(EXP / "bench_memory.py"), "--quick", "--methods",
                        "none", "--no-whole", "--detail", "none"],
                       capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr
    row = re.search(r"^none \| (\d+) \| (\d+) \| [\d.]+ \| [\d.]+ \| [\d.]+ / [\d.]+ / [\d.]+$",
                    r.stdout, re.M)
    assert row is not None, r.stdout
    assert int(row.group(2)) > 0  # the run's own peak_rss_mb from wall.csv
    assert "none at the end: RSS" in r.stdout and "in flight" in r.stdout
