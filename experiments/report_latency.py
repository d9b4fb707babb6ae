"""The ``latency_tolerance`` section of ``lab/record/REPRODUCTION.md``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from sigma_lab.studies.report import Templates, col, get, method_table, num
from sigma_lab.studies.tables import md_table

TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")


LATENCY_COLS = (
    col("AoI mean ± std (ms)", "aoi_mean", "aoi_std"),
    col("AoI p99 (ms)", "aoi_p99", nd=0),
    col("state latency (ms)", "latency_state_mean"),
    col("displacement mean / max (ms)", "displacement_mean_ms", "displacement_max_ms", nd=0,
        sep=" / "),
    col("position error mean / max (m)", "pos_err_mean", "pos_err_max", nd=(3, 2), sep=" / "),
    col("snapshots (Hz)", "snapshot_rate_hz"),
    col("aligned frames/s", "aligned_rate_hz"),
    col("triggers (Hz)", "trigger_rate_hz"),
    col("filled / extrapolated", "filled_frac", "extrapolated_frac", nd=2, sep=" / "),
)



def sec_latency(s: dict[str, Any]) -> str:
    """The latency-tolerance study."""
    parts = []
    sc = None
    for v_name, var in s["variants"].items():
        sc = var["scenario"]
        parts.append(f"*{v_name} transport:*\n\n" + md_table(*method_table(var, LATENCY_COLS)))
    assert sc is not None
    d = s["variants"].get("datagram", next(iter(s["variants"].values())))
    st = s["variants"].get("stream")
    ratio = (get(d, "bides", "aoi_mean") or math.nan) / (get(d, "hlc", "aoi_mean") or math.nan)
    lat = sc["net"]["host_link"]["latency"]
    stream_txt = ""
    if st is not None:
        stream_txt = TEMPLATES.fill(
            "latency_tolerance_stream",
            sc=sc,
            st_none_latency_state_mean=num(get(st, "none", "latency_state_mean"), 0),
            st_lockstep_trigger_rate_hz=num(get(st, "lockstep", "trigger_rate_hz"), 1),
            st_bides_f_trig_settled_hz=num(get(st, "bides", "f_trig_settled_hz"), 0),
            st_bides_extrapolated_frac=num(get(st, "bides", "extrapolated_frac"), 2),
        )
    return TEMPLATES.fill(
        "latency_tolerance",
        sc=sc,
        loss_pct=100 * sc["net"]["host_link"]["loss"]["p"],
        delay_mean_ms=1000 * lat["mean"],
        delay_std_ms=1000 * lat["std"],
        tables=chr(10).join(p + chr(10) for p in parts),
        d_none_displacement_mean_ms=num(get(d, "none", "displacement_mean_ms"), 0),
        d_none_displacement_max_ms=num(get(d, "none", "displacement_max_ms"), 0),
        d_hlc_aoi_mean=num(get(d, "hlc", "aoi_mean"), 0),
        d_bides_aoi_mean=num(get(d, "bides", "aoi_mean"), 0),
        ratio=num(ratio, 2),
        d_bides_snapshot_rate_hz=num(get(d, "bides", "snapshot_rate_hz"), 1),
        d_lockstep_trigger_rate_hz=num(get(d, "lockstep", "trigger_rate_hz"), 1),
        d_none_aoi_mean=num(get(d, "none", "aoi_mean"), 0),
        stream_txt=stream_txt,
    )
