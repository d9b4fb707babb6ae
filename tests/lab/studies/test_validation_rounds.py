"""The round of a frame at a missed knee: stages by hand, live's log, the DES's tap."""

from __future__ import annotations

import gzip
from pathlib import Path

import pandas as pd
import pytest
from sigma_lab.studies.validation.rounds import (
    des_round,
    disputed,
    live_round,
    round_md,
    round_stages,
)

from sigma_des.config import Scenario

#: Two frames in the window [1.0, 1.015) and one after it; two nodes.
ISSUE = pd.Series({0: 1.000, 1: 1.010, 2: 1.020})
TRIG = [(0, 0, 1.001), (0, 0, 1.003), (1, 0, 1.002), (0, 1, 1.011), (1, 1, 1.013),
        (0, 2, 1.021)]
STATES = [(0, 0, 1.003, 1.005), (1, 0, 1.004, 1.008), (0, 1, 1.012, 1.014),
          (1, 1, 1.015, 1.016), (1, 1, 1.015, 1.019), (0, 2, 1.022, 1.023)]
#: trigger [1, 2, 1, 3] ms (the first receipt counts), job [2, 2, 1, 2], up [2, 4, 2, 1]
#: (the first state receipt counts), round max(8, 6)... per frame: 8 and 6; period 10.
EXPECTED = {"trigger": 1.75, "job": 1.75, "up": 2.25, "round": 7.0, "period": 10.0,
            "trigger_p90": 2.7, "up_p90": 3.4, "frames": 2.0}


def test_round_stages_by_hand() -> None:
    trig = pd.DataFrame(TRIG, columns=["node", "frame", "t_recv"])
    states = pd.DataFrame(STATES, columns=["node", "frame", "t_rec", "t_recv"])
    got = round_stages(ISSUE, trig, states, 1.0, 1.015)
    assert got == pytest.approx(EXPECTED)


def test_live_round_reads_the_log_columns(tmp_path: Path) -> None:
    """Issue = the trigger rows' stamp, receipt = a state_pub row's t_trig, record and
    receipt = a state row's send and receive; republished states and other methods are
    left out."""
    rows: list[tuple[object, ...]] = []
    for f, t in ISSUE.items():
        for h in (0, 1):  # one trigger row per host; the earliest stamp is the issue
            rows.append(("lockstep", "trigger", h, -1, f, t + 0.0001 * h, t + 0.0005, "", False))
    for n, f, t in TRIG:
        if (n, f) != (0, 0) or t == 1.001:  # one state_pub row per node and frame
            rows.append(("lockstep", "state_pub", n // 1, n, f, 0.0, "", t, False))
    for i, (n, f, rec, recv) in enumerate(STATES):
        rows.append(("lockstep", "state", n, n, f, rec, recv, recv, i == 4))
    rows.append(("none", "state", 0, 0, 0, 1.0, 1.5, 1.5, False))  # another method
    df = pd.DataFrame(rows, columns=["method", "kind", "host", "node", "frame", "t_send",
                                     "t_recv", "t_trig", "republish"])
    path = tmp_path / "messages.csv.gz"
    with gzip.open(path, "wt") as fh:
        df.to_csv(fh, index=False)
    assert live_round(path, "lockstep", 1.0, 1.015) == pytest.approx(EXPECTED)


def test_disputed_sizes_hold_on_one_side_only() -> None:
    assert disputed({"live_capacity": 150, "des_capacity": 100},
                    [10, 30, 60, 100, 120, 150]) == [120, 150]
    assert disputed({"live_capacity": 60, "des_capacity": 50}, [10, 20, 30, 60, 100]) == [60]
    assert disputed({"live_capacity": None, "des_capacity": 30}, [30, 10, 20]) == [10, 20, 30]
    assert disputed({"live_capacity": 60, "des_capacity": 60}, [10, 60, 100]) == []


def test_the_reading_names_the_stage_that_differs_most() -> None:
    def row(side: str, cell: str, trigger: float, up: float, rnd: float) -> dict[str, object]:
        return {"mode": "bundle", "method": "lockstep", "nodes": 150, "cell": cell,
                "side": side, "trigger": trigger, "job": 2.0, "up": up, "round": rnd,
                "period": 10.0, "trigger_p90": 2.0, "up_p90": 5.0, "frames": 300.0}

    rows = [row("live", "a", 1.0, 4.0, 9.0), row("live", "b", 2.0, 4.4, 10.0),
            row("DES", "knee-n150-bundle", 1.8, 6.2, 12.5)]
    md = "\n".join(round_md(rows, True))
    assert "round +3.00 ms; most from `up` (+2.00 ms)" in md
    assert md.count("round +") == 1  # one reading per size
    assert round_md([], False) == []
    assert "Not split" in "\n".join(round_md([], True))


def test_des_round_on_a_small_lockstep_run() -> None:
    """Per-node messages, no CPU stage: Lock-Step holds 100 Hz (a 10 ms period, 50 frames
    in 0.5 s); a trigger takes its two 0.25 ms hops and a little more; the job is the
    0.8 ms step time; a frame's round holds at least a whole mean path."""
    sc = Scenario(nodes=4, hosts=2, duration=1.0, warmup=0.5, methods=("lockstep",))
    got = des_round(sc, "lockstep")
    assert got["period"] == pytest.approx(10.0) and got["frames"] == 50
    assert 0.5 <= got["trigger"] <= got["trigger_p90"] < 0.6
    assert 0.5 <= got["up"] < 0.6
    assert got["job"] == pytest.approx(0.8, abs=0.1)
    assert got["round"] >= got["trigger"] + got["job"] + got["up"]
