"""Typed reports and the collector's own spec."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from sigma_des.errors import ConfigError
from sigma_des.metrics.collector import Collector, CollectorSpec
from sigma_des.metrics.reports import AlignerReport, NetReport, RunReport


def _net() -> SimpleNamespace:
    links = [SimpleNamespace(name="host0.up", bytes=1000, packets=4),
             SimpleNamespace(name="host0.down", bytes=3000, packets=6)]
    return SimpleNamespace(links=lambda: links, retransmissions=2, gave_up=1, broker_work=0.5,
                           broker_max_wait=0.004)


def test_net_report_reads_the_public_counters() -> None:
    rep = NetReport.of(_net())
    assert rep.links == (("host0.up", 1000, 4), ("host0.down", 3000, 6))
    assert (rep.retransmissions, rep.gave_up, rep.broker_work, rep.broker_max_wait) == (
        2, 1, 0.5, 0.004)


def test_collector_spec_is_validated() -> None:
    with pytest.raises(ConfigError, match="warmup"):
        CollectorSpec(nodes=2, warmup=3.0, duration=2.0, f_trig=100.0, history_frames=16,
                      stall_threshold=0.1)
    with pytest.raises(ConfigError, match="stall_threshold"):
        CollectorSpec(nodes=2, warmup=0.0, duration=2.0, f_trig=100.0, history_frames=16,
                      stall_threshold=0.0)


def test_finish_takes_the_typed_reports() -> None:
    spec = CollectorSpec(nodes=2, warmup=0.0, duration=2.0, f_trig=100.0, history_frames=16,
                         stall_threshold=0.1)
    col = Collector(spec, "lockstep")
    col.snapshot(1.0)
    out = col.finish(RunReport(f_trig=50.0, rollbacks=3, resim_steps=7, history_misses=1,
                               wall_seconds=0.5, events=100),
                     AlignerReport(peak_bytes=640, evicted=1, rejoined=0, rerequests=5),
                     NetReport.of(_net()))
    m = out["metrics"]
    assert m["throughput_mbps"] == 4000 * 8 / 2.0 / 1e6
    assert m["throughput_max_link_mbps"] == 3000 * 8 / 2.0 / 1e6
    assert m["packets_per_s"] == 10 / 2.0
    assert (m["buffer_bytes_peak"], m["evicted"], m["rerequests"], m["rollbacks"]) == (
        640, 1, 5, 3)
    assert m["f_trig_final_hz"] == 50.0 and m["broker_util"] == 0.25
    assert m["stalls"] == 2  # the gaps 0 -> 1 s and 1 -> 2 s
    assert out["links_mbps"] == {"host0.up": 0.004, "host0.down": 0.012}
    assert out["wall"]["events"] == 100 and out["wall"]["events_per_s"] == 200.0
    assert math.isnan(m["spread_mean"]) and np.isnan(m["aoi_mean"])
