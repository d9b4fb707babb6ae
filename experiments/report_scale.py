"""The ``scale_200`` and ``scale_1000`` sections of ``lab/record/REPRODUCTION.md``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from sigma_lab.studies.report import Templates, col, method_table, num
from sigma_lab.studies.tables import md_table

TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")


SCALE_200_COLS = (
    col("state latency (ms)", "latency_state_mean", nd=2),
    col("AoI mean ± std (ms)", "aoi_mean", "aoi_std", nd=2),
    col("AoI p99 (ms)", "aoi_p99"),
    col("server buffer peak (KiB)", "buffer_bytes_peak", fn=lambda x: x / 1024),
    col("throughput (Mbps)", "throughput_mbps"),
    col("snapshots (Hz)", "snapshot_rate_hz"),
    col("triggers (Hz)", "trigger_rate_hz"),
    col("frame spread", "spread_mean", nd=2),
)
SCALE_1000_COLS = (
    col("throughput (Mbps)", "throughput_mbps"),
    col("AoI mean ± std (ms)", "aoi_mean", "aoi_std"),
    col("state latency (ms)", "latency_state_mean"),
    col("broker load (%)", "broker_util", nd=0, fn=lambda x: 100 * (x or math.nan)),
    col("achieved triggers (Hz)", "trigger_rate_hz"),
    col("f_trig in force, last quarter (Hz)", "f_trig_settled_hz"),
    col("snapshots (Hz)", "snapshot_rate_hz"),
)

def sec_scale_200(s: dict[str, Any]) -> str:
    """The 200-node study."""
    var = s["variants"]["default"]
    sc = var["scenario"]
    t = md_table(*method_table(var, SCALE_200_COLS))
    b = var["methods"].get("bides", {})
    ls = var["methods"].get("lockstep", {})
    h = var["methods"].get("hlc", {})
    return TEMPLATES.fill(
        "scale_200",
        sc=sc,
        t=t,
        b_aoi_mean=num(b.get("aoi_mean"), 1),
        b_aoi_std=num(b.get("aoi_std"), 1),
        b_snapshot_rate_hz=num(b.get("snapshot_rate_hz"), 0),
        h_aoi_mean=num(h.get("aoi_mean"), 1),
        render_offset=num((sc.get("render_phase", 0.0) - sc.get("align_phase", 0.0)) % 1.0, 2),
        b_aoi_time_avg=num(b.get("aoi_time_avg"), 1),
        sawtooth_ms=num(500.0 / float(sc["f_align"]), 1),
        ls_aoi_mean=num(ls.get("aoi_mean"), 1),
    )


def sec_scale_1000(s: dict[str, Any]) -> str:
    """The 1000-node study."""
    var = s["variants"]["default"]
    sc = var["scenario"]
    cap = s.get("extra", {}).get("broker", {})
    rows = []
    for v_name, v in s["variants"].items():
        suffix = "" if v_name == "default" else f" ({v_name.replace('_', ' ')})"
        head, vrows = method_table(v, SCALE_1000_COLS, lambda lab, x=suffix: lab + x)
        rows += vrows
    t = md_table(head, rows)
    c = cap.get("default", {})
    cf = cap.get("fast_broker", {})
    b = var["methods"].get("bides", {})
    n = var["methods"].get("none", {})
    ls = var["methods"].get("lockstep", {})
    q = s.get("extra", {}).get("bides_f_trig_last_quarter", {})
    pub = sc["broker"]["publish_service"]
    dlv = sc["broker"]["delivery_service"]
    pub_us = 1e6 * (pub["value"] if pub["dist"] == "constant" else pub["mean"])
    dlv_us = 1e6 * (dlv["value"] if dlv["dist"] == "constant" else dlv["mean"])
    return TEMPLATES.fill(
        "scale_1000",
        sc=sc,
        nodes_per_host=sc["nodes"] // sc["hosts"],
        pub_us=pub_us,
        dlv_us=dlv_us,
        t=t,
        broker_ms_per_frame=num(1000 * c.get("broker_s_per_frame", math.nan), 2),
        command_load_pct=num(100 * c.get("command_load", math.nan), 0),
        offered_load_pct=num(100 * c.get("offered_load_at_nominal", math.nan), 0),
        c_max_trigger_hz=num(c.get("max_trigger_hz"), 0),
        cf_max_trigger_hz=num(cf.get("max_trigger_hz"), 0),
        q_mean=num(q.get("mean"), 1),
        q_min=num(q.get("min"), 1),
        q_max=num(q.get("max"), 1),
        n_throughput_mbps=num(n.get("throughput_mbps"), 0),
        ls_trigger_rate_hz=num(ls.get("trigger_rate_hz"), 0),
        ls_aoi_mean=num(ls.get("aoi_mean"), 1),
        ls_aoi_std=num(ls.get("aoi_std"), 1),
        b_aoi_mean=num(b.get("aoi_mean"), 1),
        b_aoi_std=num(b.get("aoi_std"), 1),
    )
