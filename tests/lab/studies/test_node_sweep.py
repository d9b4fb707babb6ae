"""studies/node_sweep.py: the node-count sweep's grid, key figures, verdict, table, summary.

Everything is computed from given numbers; the sweep itself is smoke-run by
tests/experiments/test_sweep_nodes.py.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from sigma_lab.studies import node_sweep as ns
from sigma_lab.studies.node_sweep import Figures

from sigma_des.errors import ConfigError
from sigma_des.sweep import RunReport


def _cell(mean: float, ci95: float = 0.0, n: float = 2.0) -> dict[str, float]:
    return {"mean": mean, "ci95": ci95, "n": n}


def _fig(aoi: dict[str, dict[int, float]]) -> Figures:
    """Figures with the given mean AoI per (method, N) and fixed other metrics."""
    return {
        m: {
            n: {"aoi_mean": _cell(a, 0.25), "latency_state_mean": _cell(0.5),
                "snapshot_rate_hz": _cell(60.0), "trigger_rate_hz": _cell(100.0)}
            for n, a in per_n.items()
        }
        for m, per_n in aoi.items()
    }


def test_key_figures_keep_the_key_metrics_by_method_and_n() -> None:
    agg: list[dict[str, Any]] = [
        {"nodes": 10, "method": "bides", "metric": "aoi_mean", "mean": 15.0, "ci95": 0.5,
         "n": 5},
        {"nodes": "20", "method": "bides", "metric": "aoi_p99", "mean": 30.0, "ci95": 1.0,
         "n": 5},
        {"nodes": 10, "method": "bides", "metric": "rollbacks", "mean": 0.0, "ci95": 0.0,
         "n": 5},
        {"nodes": 10, "method": "hlc", "metric": "snapshot_rate_hz", "mean": 60.0,
         "ci95": math.nan, "n": 1},
    ]
    fig = ns.key_figures(agg)
    assert fig["bides"] == {10: {"aoi_mean": {"mean": 15.0, "ci95": 0.5, "n": 5}},
                            20: {"aoi_p99": {"mean": 30.0, "ci95": 1.0, "n": 5}}}
    assert list(fig["hlc"][10]) == ["snapshot_rate_hz"]


def test_lockstep_degrades_where_its_aoi_exceeds_1_5_times_bides() -> None:
    # 1.5 x exactly is not "more than"; NaN is passed over; 50 is the first beyond
    fig = _fig({"lockstep": {10: 15.0, 20: math.nan, 50: 24.1, 100: 40.0},
                "bides": {10: 10.0, 20: 10.0, 50: 16.0, 100: 16.0}})
    assert ns.lockstep_degradation(fig) == 50
    assert ns.degrade_line(fig, 50) == "lock-step degrades (AoI > 1.5 × BiDES's): N = 50"
    calm = _fig({"lockstep": {10: 15.0}, "bides": {10: 10.0}})
    assert ns.lockstep_degradation(calm) is None
    assert ns.degrade_line(calm, None).endswith("BiDES's): not within the grid")
    assert ns.lockstep_degradation(_fig({"lockstep": {10: 99.0}})) is None
    assert ns.degrade_line(_fig({"lockstep": {10: 99.0}}), None) == ""


def test_figure_table_rows_in_method_order() -> None:
    fig = _fig({"bides": {20: 14.744, 10: 15.2}, "none": {10: 14.71}})
    assert ns.figure_table(fig).split("\n") == [
        "     N    method           AoI ms   lat ms  snap Hz  trig Hz",
        "    10      none     14.71 ± 0.25     0.50     60.0    100.0",
        "    10     bides     15.20 ± 0.25     0.50     60.0    100.0",
        "    20     bides     14.74 ± 0.25     0.50     60.0    100.0",
    ]


def test_build_sweep_grid_seeds_duration_and_store(tmp_path: Path) -> None:
    quick = ns.build_sweep(quick=True, out=tmp_path / "q")
    assert quick.points == [{"nodes": 10, "hosts": 1}, {"nodes": 20, "hosts": 1}]
    assert quick.seeds == [1, 2]
    assert (quick.base.duration, quick.base.warmup) == (0.5, 0.1)
    assert Path(quick.store.path) == tmp_path / "q" / "sweep.sqlite"
    sw = ns.build_sweep("30, 45", duration=2.0, seeds="3", methods="none,bides",
                     store=tmp_path / "s.sqlite", sets=["f_trig=50.0"])
    assert sw.points == [{"nodes": 30, "hosts": 2}, {"nodes": 45, "hosts": 3}]
    assert (sw.seeds, sw.methods) == ([1, 2, 3], ["none", "bides"])
    assert (sw.base.duration, sw.base.warmup, sw.base.f_trig) == (2.0, 1.0, 50.0)
    text = ns.estimate_text(sw, 2, False)
    assert text.startswith(f"12 runs to do (store {tmp_path / 's.sqlite'}); rough estimate ")
    assert text.endswith(" on 2 worker(s) — interrupt at will, rerun to resume")
    with pytest.raises(ConfigError, match="must be a comma list of integers, got '1,x'"):
        ns.build_sweep("1,x", store=tmp_path / "bad.sqlite")


def test_summary_records_plan_failures_and_verdict(tmp_path: Path) -> None:
    sw = ns.build_sweep("10", seeds="1", methods="lockstep,bides", store=tmp_path / "s.sqlite",
                     duration=1.0)
    rep = RunReport(total=2, failures=[(("abc", 1, "bides"), "boom")])
    fig = _fig({"lockstep": {10: 15.0}, "bides": {10: 10.0}})
    s = ns.summary(sw, rep, fig, None)
    assert s == {
        "nodes": [10], "hosts": [1], "methods": ["lockstep", "bides"], "seeds": [1],
        "duration_s": 1.0, "warmup_s": 0.1, "runs": 2,
        "failed": [{"key": ["abc", 1, "bides"], "error": "boom"}],
        "lockstep_degrades_at": None,
        "degrade_rule": "lockstep aoi_mean > 1.5 x bides aoi_mean",
        "figures": {m: {"10": v[10]} for m, v in fig.items()},
    }


def test_plot_figures_writes_one_png_per_metric(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    fig = _fig({"lockstep": {10: 15.0, 20: 16.0}, "bides": {10: 10.0, 20: 11.0}})
    paths = ns.plot_figures(fig, tmp_path)
    assert [p.name for p in paths] == [
        "aoi_vs_nodes.png", "latency_vs_nodes.png", "snapshot_rate_vs_nodes.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
