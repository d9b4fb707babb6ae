"""The live receive-path figures (studies/validation/livepath.py) on a hand-built run:
bundle size from the server's ledger, loop figures per wake-up, trigger-timer lateness
and the state latency by receipt rank, each computed by hand below."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sigma_lab.studies.validation.livepath import path_md, path_rows, rank_quartiles

COLS = ["method", "kind", "host", "node", "frame", "t_send", "t_recv", "t_trig", "cost",
        "republish"]


def _run(d: Path) -> Path:
    """One bundled ``none`` run, warmup 1 s, window 2 s, f_trig 100 Hz: frames 100 and 101
    (issued at 1.0002 and 1.0107: the second 0.5 ms later than the first), 8 states
    (4 a frame) in 3 PUBLISHes, one command PUBLISH of 2 records to host 0; one trigger
    outside the window (frame 99, issued at 0.99) and one state before it."""
    rows = [
        ("none", "trigger_sent", -1, -1, 99, 0.99, math.nan, math.nan, math.nan, 0.0),
        ("none", "trigger_sent", -1, -1, 100, 1.0002, math.nan, math.nan, math.nan, 0.0),
        ("none", "trigger_sent", -1, -1, 101, 1.0107, math.nan, math.nan, math.nan, 0.0),
        ("none", "trigger", 0, -1, 100, 1.0002, 1.0012, math.nan, math.nan, 0.0),
        ("none", "trigger", 0, -1, 101, 1.0107, 1.0137, math.nan, math.nan, 0.0),
        ("none", "command", 0, 0, 7, 1.2, 1.201, math.nan, math.nan, 0.0),
        ("none", "command", 0, 1, 7, 1.2, 1.201, math.nan, math.nan, 0.0),
        ("none", "state", 0, 0, 98, 0.995, 0.999, 0.999, math.nan, 0.0),
    ]
    # frame 100: latencies 1, 2, 3, 4 ms in receipt order; frame 101: 5, 6, 7, 8 ms
    for f, base in ((100, 1.003), (101, 1.013)):
        for j in range(4):
            lat = (j + 1 + (f - 100) * 4) * 1e-3
            rows.append(("none", "state", 0, j, f, base + j * 1e-4, base + j * 1e-4 + lat,
                         math.nan, math.nan, 0.0))
    run = d / "n4-bundle"
    run.mkdir()
    pd.DataFrame(rows, columns=COLS).to_csv(run / "messages.csv.gz", index=False)
    # the server's ledger: 2 triggers + 1 command PUBLISH + 3 state PUBLISHes in the window
    pd.DataFrame([{"method": "none", "process": "server", "window_s": 2.0, "cpu_s": 0.5,
                   "messages": 6, "wakes": 100, "calls": 400, "loop_cpu_s": 0.02,
                   "loop_wall_s": 0.03, "runq_wait_s": 0.25}]).to_csv(run / "cpu.csv",
                                                                   index=False)
    (run / "summary.json").write_text(json.dumps(
        {"scenario": {"warmup": 1.0, "f_trig": 100.0}, "live": {"none": {"bundle": True}}}))
    return run


def test_the_figures_of_a_hand_built_run(tmp_path: Path) -> None:
    (r,) = path_rows(_run(tmp_path), "n4-bundle")
    assert r["records"] == 8
    assert r["records_per_publish"] == pytest.approx(8 / 3)
    assert r["server_wakes_hz"] == pytest.approx(50.0)
    assert r["calls_per_wake"] == pytest.approx(4.0)
    assert r["loop_cpu_per_wake_ms"] == pytest.approx(0.2)
    assert r["loop_wall_per_wake_ms"] == pytest.approx(0.3)
    assert r["server_runq_per_cpu"] == pytest.approx(0.5)
    assert r["latency_ms"] == pytest.approx(4.5)
    assert r["trigger_latency_ms"] == pytest.approx((1.0 + 3.0) / 2)
    # lateness 0.2 and 0.7 ms after the grid, less the 1st percentile (0.2 + 0.005 ms)
    assert r["trigger_late_ms"] == pytest.approx((0.0 + 0.5) / 2 - 0.005)
    # receipt ranks 1..4 in each frame: quartile q holds rank q of both frames
    assert [r[f"rank_q{q}_ms"] for q in (1, 2, 3, 4)] == pytest.approx([3.0, 4.0, 5.0, 6.0])
    assert path_md([r])[2].startswith("| n4-bundle | none | 8 | 2.67 |")


def test_lockstep_has_no_trigger_lateness(tmp_path: Path) -> None:
    run = _run(tmp_path)
    df = pd.read_csv(run / "messages.csv.gz")
    df["method"] = "lockstep"
    df.to_csv(run / "messages.csv.gz", index=False)
    pd.read_csv(run / "cpu.csv").assign(method="lockstep").to_csv(run / "cpu.csv", index=False)
    (run / "summary.json").write_text(json.dumps(
        {"scenario": {"warmup": 1.0, "f_trig": 100.0}, "live": {"lockstep": {"bundle": True}}}))
    (r,) = path_rows(run, "n4-bundle")
    assert math.isnan(r["trigger_late_ms"]) and r["records"] == 8


def test_rank_quartiles_of_uneven_frames() -> None:
    """Frame 1 has 4 states, frame 2 has 2: quartiles of 4 ranks; ranks 3-4 only frame 1."""
    q = rank_quartiles(np.array([1, 1, 1, 1, 2, 2]), np.array([0.1, 0.2, 0.3, 0.4, 0.1, 0.2]),
                       np.array([1.0, 2.0, 3.0, 4.0, 10.0, 20.0]))
    assert q == pytest.approx([5.5, 11.0, 3.0, 4.0])
