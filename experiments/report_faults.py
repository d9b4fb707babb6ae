"""The ``faults`` section of ``lab/record/REPRODUCTION.md``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from sigma_lab.studies.report import Templates, get, labels, num
from sigma_lab.studies.tables import md_table

TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")


def sec_faults(s: dict[str, Any]) -> str:
    """The fault study."""
    ex = s.get("extra", {})
    win = ex.get("windows", {})
    fw = ex.get("fault_window_s", {})
    tgt = ex.get("target", {})
    parts = []
    sc = None
    for v_name, var in s["variants"].items():
        sc = var["scenario"]
        rows = []
        for lab in labels(var):
            w = win.get(v_name, {}).get(lab, {})
            rows.append(
                [
                    lab,
                    f"{num(w.get('aoi_before_ms'), 0)} / {num(w.get('aoi_during_ms'), 0)} / "
                    f"{num(w.get('aoi_after_ms'), 0)}",
                    f"{num(w.get('aligned_rate_before_hz'), 0)} / "
                    f"{num(w.get('aligned_rate_during_hz'), 0)} / "
                    f"{num(w.get('aligned_rate_after_hz'), 0)}",
                    num(get(var, lab, "stall_time_s"), 2),
                    num(get(var, lab, "evicted"), 1),
                    num(get(var, lab, "extrapolated_frac"), 3),
                    num(w.get("recovery_s"), 2),
                ]
            )
        a, b = fw.get(v_name, (math.nan, math.nan))
        parts.append(
            f"*{v_name}* (fault window {num(a, 1)}–{num(b, 1)} s):\n\n"
            + md_table(
                [
                    "method",
                    "AoI before / during / after (ms)",
                    "aligned frames/s before / during / after",
                    "stalled (s)",
                    "evicted",
                    "extrapolated",
                    "recovery (s)",
                ],
                rows,
            )
        )
    assert sc is not None
    return TEMPLATES.fill(
        "faults",
        sc=sc,
        tgt_node=tgt.get("node"),
        tgt_host=tgt.get("host"),
        tgt_eviction_timeout_s=tgt.get("eviction_timeout_s"),
        tables=chr(10).join(p + chr(10) for p in parts),
    )
