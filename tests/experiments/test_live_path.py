"""experiments/live_path.py on a one-run campaign: its table and CSV, and exit 2 with the
option named for a folder without kept runs or a glob matching none."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "live_path.py"


def _campaign(d: Path) -> Path:
    """A campaign with one kept run ``n2-bundle``: 2 states of frame 100 (1 and 3 ms) in
    one PUBLISH, and the trigger that started them."""
    run = d / "live" / "n2-bundle"
    run.mkdir(parents=True)
    cols = ["method", "kind", "host", "node", "frame", "t_send", "t_recv", "t_trig", "cost",
            "republish"]
    rows = [("none", "trigger_sent", -1, -1, 100, 1.0, None, None, None, 0.0),
            ("none", "trigger", 0, -1, 100, 1.0, 1.001, None, None, 0.0),
            ("none", "state", 0, 0, 100, 1.002, 1.003, None, None, 0.0),
            ("none", "state", 0, 1, 100, 1.002, 1.005, None, None, 0.0)]
    pd.DataFrame(rows, columns=cols).to_csv(run / "messages.csv.gz", index=False)
    pd.DataFrame([{"method": "none", "process": "server", "window_s": 2.0, "cpu_s": 0.4,
                   "messages": 2, "wakes": 10, "calls": 30, "loop_cpu_s": 0.01,
                   "loop_wall_s": 0.02, "runq_wait_s": 0.2}]).to_csv(run / "cpu.csv",
                                                                  index=False)
    (run / "summary.json").write_text(json.dumps(
        {"scenario": {"warmup": 1.0, "f_trig": 100.0}, "live": {"none": {"bundle": True}}}))
    return d


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)


def test_table_and_csv(tmp_path: Path) -> None:
    out = tmp_path / "p.csv"
    r = _run(str(_campaign(tmp_path)), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "| n2-bundle | none | 2 | 2 | 5 | 3 |" in r.stdout
    row = pd.read_csv(out).iloc[0]
    assert abs(row["latency_ms"] - 2.0) < 1e-9 and row["records_per_publish"] == 2.0


def test_bad_input_exits_2(tmp_path: Path) -> None:
    r = _run(str(tmp_path))
    assert r.returncode == 2 and "campaign" in r.stderr
    r = _run(str(_campaign(tmp_path)), "--cells", "n9*")
    assert r.returncode == 2 and "--cells" in r.stderr
