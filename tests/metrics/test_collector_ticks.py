"""Per-render-tick series are cut to whole ticks (a run interrupted mid-tick)."""

from __future__ import annotations

from sigma_des.metrics.collector import whole_ticks


def test_whole_ticks_cuts_a_partial_tick() -> None:
    ts = {"t": [0.0, 0.1, 0.2], "aoi_mean": [1.0, 2.0], "f_trig": [100.0, 100.0, 100.0]}
    out = whole_ticks(ts)
    assert {k: v.tolist() for k, v in out.items()} == {
        "t": [0.0, 0.1], "aoi_mean": [1.0, 2.0], "f_trig": [100.0, 100.0]}


def test_whole_ticks_keeps_a_complete_run() -> None:
    ts = {"t": [0.0, 0.5], "aoi_mean": [3.0, 4.0]}
    assert {k: v.tolist() for k, v in whole_ticks(ts).items()} == ts
    assert whole_ticks({}) == {}
