"""The ``alignment_cost`` section of ``lab/record/REPRODUCTION.md``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sigma_lab.studies.report import Templates, num
from sigma_lab.studies.tables import md_table

TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")


def sec_cost(s: dict[str, Any]) -> str:
    """The alignment-cost study."""
    cost = s["cost"]
    ns = sorted(cost, key=int)
    rows = []
    for n in ns:
        c = cost[n]
        row = [f"{int(n):,}"]
        for m in ("bides", "hlc", "lockstep"):
            x = c.get(m, {})
            row.append(f"{num(x.get('align_median_ms'), 3)} / {num(x.get('align_p95_ms'), 3)}")
            row.append(num(x.get("ingest_median_ms"), 2))
        rows.append(row)
    t = md_table(
        [
            "n",
            "BiDES Algorithm 1 median / p95 (ms)",
            "BiDES inserts per frame (ms)",
            "HLC tick median / p95 (ms)",
            "HLC pushes per tick (ms)",
            "Lock-Step tick median / p95 (ms)",
            "Lock-Step arrivals per frame (ms)",
        ],
        rows,
    )
    p = s.get("params", {})
    mach = s.get("machine", {})
    b1000 = cost.get("1000", {}).get("bides", {}).get("align_median_ms")
    period = 1000.0 / float(p.get("f_align", 60.0))
    ok = [int(n) for n in ns if (cost[n].get("bides", {}).get("align_median_ms") or 1e9) < period]
    fits = f"{max(ok):,}" if ok else "none of the tested n"
    big = ns[-1]
    b_big = cost[big].get("bides", {}).get("align_median_ms")
    return TEMPLATES.fill(
        "alignment_cost",
        p_k=p.get("k"),
        p_theta_lag=p.get("theta_lag"),
        hole_pct=100 * p.get("hole_p", 0),
        mach_processor=mach.get("processor", '?'),
        mach_python=mach.get("python", '?'),
        t=t,
        b1000=num(b1000, 2),
        b_big=num(b_big, 1),
        n_big=int(big),
        period=num(period, 1),
        p_f_align=num(p.get("f_align"), 0),
        fits=fits,
    )
