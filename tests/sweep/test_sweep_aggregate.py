"""Aggregation over seeds, checked by hand: mean, sample std, n, t-based 95 % CI."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest
from sweep_helpers import tiny_base

from sigma_des import Scenario
from sigma_des.sweep import Sweep, aggregate_rows, t975

#: Student t_{0.975, df} from printed tables.
T_TABLE = {1: 12.706204736, 2: 4.302652730, 3: 3.182446305, 4: 2.776445105, 9: 2.262157163}


def test_t_quantiles_match_the_table() -> None:
    for df, t in T_TABLE.items():
        assert t975(df) == pytest.approx(t, abs=1e-8)


def test_hand_computed_groups() -> None:
    rows: list[dict[str, Any]] = [
        # group A: 1, 2, 3, 4 -> mean 2.5, var = (2.25+0.25+0.25+2.25)/3 = 5/3
        *(
            {"p": 10, "method": "none", "metric": "x", "value": v, "unit": "ms"}
            for v in (1, 2, 3, 4)
        ),
        # group B: 2, 4, NaN -> NaN left out: n 2, mean 3, std sqrt(2), ci 12.7062 * sqrt(2)/sqrt(2)
        *(
            {"p": 10, "method": "bides", "metric": "x", "value": v, "unit": "ms"}
            for v in (2.0, math.nan, 4.0)
        ),
        # group C: a single value -> std and ci undefined
        {"p": 20, "method": "none", "metric": "x", "value": 7.0, "unit": "ms"},
        # group D: only NaN -> n 0
        {"p": 20, "method": "none", "metric": "y", "value": math.nan, "unit": "1"},
    ]
    agg = aggregate_rows(rows, ["p", "method", "metric"])
    assert [(r["p"], r["method"], r["metric"]) for r in agg] == [
        (10, "none", "x"),
        (10, "bides", "x"),
        (20, "none", "x"),
        (20, "none", "y"),
    ]
    a, b, c, d = agg
    assert (a["n"], a["mean"], a["unit"]) == (4, 2.5, "ms")
    assert a["std"] == pytest.approx(math.sqrt(5 / 3), rel=1e-14)
    assert a["ci95"] == pytest.approx(3.182446305 * math.sqrt(5 / 3) / 2, rel=1e-9)
    assert (b["n"], b["mean"]) == (2, 3.0)
    assert b["std"] == pytest.approx(math.sqrt(2), rel=1e-14)
    assert b["ci95"] == pytest.approx(12.706204736, rel=1e-9)
    assert (c["n"], c["mean"]) == (1, 7.0) and math.isnan(c["std"]) and math.isnan(c["ci95"])
    assert d["n"] == 0 and math.isnan(d["mean"])


def seed_task(sc: Scenario, method: str) -> Mapping[str, Any]:
    """A synthetic task: metric ``x`` = seed (+100 for bides), ``y`` = nodes."""
    return {"metrics": {"x": sc.seed + (100.0 if method == "bides" else 0.0), "y": sc.nodes}}


def test_sweep_aggregate_of_synthetic_records(tmp_path: Path) -> None:
    with Sweep(
        tiny_base(),
        {"nodes": [3, 5]},
        ["none", "bides"],
        [1, 2, 3, 4, 5, 6, 7, 8, 9, 10],
        tmp_path / "s.sqlite",
        task=seed_task,
    ) as sw:
        sw.run(client="inprocess", progress=False)
        agg = {(r["nodes"], r["method"], r["metric"]): r for r in sw.aggregate()}
        assert len(agg) == 8
        sd = math.sqrt(sum((s - 5.5) ** 2 for s in range(1, 11)) / 9)  # = sqrt(55/6)
        for n in (3, 5):
            for m, off in (("none", 0.0), ("bides", 100.0)):
                r = agg[(n, m, "x")]
                assert (r["n"], r["mean"]) == (10, 5.5 + off)
                assert r["std"] == pytest.approx(sd, rel=1e-14)
                assert r["ci95"] == pytest.approx(2.262157163 * sd / math.sqrt(10), rel=1e-9)
                y = agg[(n, m, "y")]
                assert (y["mean"], y["std"], y["ci95"]) == (n, 0.0, 0.0)
        runs, aggp = sw.write(tmp_path / "out")
        text = runs.read_text().splitlines()
        assert text[0] == "nodes,config_hash,seed,method,metric,value,unit"
        assert len(text) == 1 + 2 * 2 * 10 * 2
        assert aggp.read_text().splitlines()[0] == (
            "nodes,config_hash,method,metric,unit,n,mean,std,ci95"
        )
