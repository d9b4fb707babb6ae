"""The validation's misses: which rows are misses, their spread, load and reading."""

from __future__ import annotations

import math
from typing import Any

import pytest
from sigma_lab.studies.validation.misses import miss_md, miss_rows


def _row(cell: str, des: float, runs: list[float], *, within: bool = False,
         metric: str = "latency_state_mean", regime: str = "node-below", mode: str = "node",
         nodes: int = 30, impairment: str = "", held_out: bool = True,
         scored: bool = True) -> dict[str, Any]:
    live = sum(runs) / len(runs)
    pp = metric == "missed_frac"
    return {"cell": cell, "method": "hlc", "metric": metric, "des": des, "live": live,
            "rel_error": 100 * (des - live) if pp else (des - live) / live,
            "error_unit": "pp" if pp else "rel", "live_runs": " ".join(map(str, runs)),
            "within_band": within, "passed": within if scored else "", "held_out": held_out,
            "regime": regime, "mode": mode,
            "nodes": nodes, "impairment": impairment}


def test_each_rule_in_order() -> None:
    rows = [
        _row("a", 10.0, [8.0, 12.0]),  # spread 40 % > 15 %, DES inside -> live spread
        _row("b", 5.0, [8.0, 12.0], regime="node-near"),  # outside: near capacity
        _row("c", 5.0, [8.0, 8.4], impairment="loss5"),
        _row("d", 5.0, [8.0, 8.4], impairment="lat5"),
        _row("e", 3.0, [2.0, 2.1], mode="bundle", nodes=10),  # above live, below cal's N
        _row("f", 1.0, [2.0, 2.1], mode="bundle", nodes=10),  # below live: not bundles
        _row("g", 5.0, [8.0, 8.4], within=True),  # in band: no miss
        _row("h", 5.0, [8.0, 8.4], held_out=False),  # calibration run: not scored here
        _row("i", 50.0, [80.0, 84.0], metric="trigger_rate_hz", scored=False),  # live slowed
    ]
    rows += [_row("q", 5.0, [8.0, 8.4]), _row("r", 9.0, [8.0, 8.4])]  # below / above live
    busy = [{"cell": c, "method": "hlc", "kind": "host", "processes": 2, "loop_busy": 0.5,
             "runq_cores": 0.5} for c in ("q", "r")]  # 2 x 0.5 = 1 run-queue core
    got = {m["cell"]: m["reading"] for m in miss_rows(rows, busy, cal_nodes=20)}
    assert got == {"a": "live spread", "b": "near capacity", "c": "loss",
                   "d": "added latency", "e": "small bundles", "f": "below capacity",
                   "q": "live run queue", "r": "below capacity"}


def test_spread_direction_and_the_live_load_of_the_cells_runs() -> None:
    rows = [_row("n30", 6.0, [8.0, 10.0, 12.0], regime="node-near"),
            _row("m", 0.10, [0.30, 0.36], metric="missed_frac")]
    procs = [
        {"cell": "n30", "method": "hlc", "kind": "server", "processes": 1, "loop_busy": 0.6,
         "runq_cores": 0.2},
        {"cell": "n30", "method": "hlc", "kind": "host", "processes": 2, "loop_busy": 0.3,
         "runq_cores": 0.1},
        {"cell": "n30-c2", "method": "hlc", "kind": "server", "processes": 1,
         "loop_busy": 0.8, "runq_cores": 0.4},
        {"cell": "n30-c2", "method": "none", "kind": "server", "processes": 1,
         "loop_busy": 9.0, "runq_cores": 9.0},  # another method: not counted
        {"cell": "n300", "method": "hlc", "kind": "server", "processes": 1,
         "loop_busy": 9.0, "runq_cores": 9.0},  # another cell with the same prefix
    ]
    a, b = miss_rows(rows, procs, cal_nodes=20)
    assert a["spread"] == pytest.approx(0.4) and a["runs"] == 3 and a["direction"] == "below"
    assert not a["des_in_runs"]
    assert a["server_loop_busy"] == pytest.approx(0.7)  # mean of the two runs' servers
    # run-queue cores per run: 0.2 + 2 x 0.1 = 0.4 and 0.4; their mean
    assert a["runq_cores"] == pytest.approx(0.4)
    assert b["spread"] == pytest.approx(6.0) and b["error_unit"] == "pp"
    assert math.isnan(b["server_loop_busy"])
    text = "\n".join(miss_md([a, b]))
    assert "| near capacity | latency_state_mean | 1 | 0 |" in text
    assert "| n30 | hlc | latency_state_mean | 6 | 10 (3) | -40 % | 40 % | no |" in text
    assert "| -23.0 pp | 6 pp | no |" in text  # 0.10 against the runs' mean 0.33


def test_no_misses_says_so() -> None:
    assert miss_md([])[-1] == "No held-out cell missed its band."
