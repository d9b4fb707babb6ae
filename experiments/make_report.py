#!/usr/bin/env python
"""Regenerate ``docs/REPRODUCTION.md`` from the studies' outputs.

Reads ``summary.json`` of every study under the outputs directory (default
``out/``): ``scale_200``, ``scale_1000``, ``latency_tolerance``, ``alignment_cost``,
``faults`` and, if present, ``sweep_nodes``; for each it writes the paper's figure,
ours (tables), the command that produced ours, and why they differ. A study
whose outputs are missing is listed with the command that would produce them.

Examples::

    python experiments/make_report.py                          # out/ -> docs/REPRODUCTION.md
    python experiments/make_report.py --outputs /tmp/q --report /tmp/q/REPORT.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sigma_des.studies import md_table

ROOT = Path(__file__).resolve().parent.parent
#: The sections' prose, one ``str.format`` template per section (``experiments/templates``).
TEMPLATES = Path(__file__).resolve().parent / "templates"
STUDIES = ("scale_200", "scale_1000", "latency_tolerance", "alignment_cost", "faults")
ORDER = ("none", "lockstep", "lockstep_evict", "hlc", "bides")


# ------------------------------------------------------------------ formatting


def fill(name: str, **fields: Any) -> str:
    """Template ``templates/<name>.md`` (its final newline dropped) with ``fields`` filled in."""
    text = (TEMPLATES / f"{name}.md").read_text(encoding="utf-8").removesuffix("\n")
    return text.format(**fields)


def num(x: Any, nd: int = 1) -> str:
    """A number with ``nd`` decimals ("–" for missing or NaN; large numbers unchanged)."""
    if x is None or isinstance(x, str):
        return "–" if x is None else str(x)
    x = float(x)
    if not math.isfinite(x):
        return "–"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{nd}f}"


def labels(var: dict[str, Any]) -> list[str]:
    """Method labels of a variant in canonical order."""
    ms = list(var["methods"])
    return sorted(ms, key=lambda m: ORDER.index(m) if m in ORDER else len(ORDER))


def get(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Mean over seeds of one metric (None if absent)."""
    return var["methods"].get(lab, {}).get(metric)


def sd(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Standard deviation over seeds of one metric (None if absent)."""
    return var.get("std", {}).get(lab, {}).get(metric)


def provenance(s: dict[str, Any]) -> str:
    """Command, seeds and version line of a study."""
    mode = " (**quick mode** — a smoke test, not the study)" if s.get("quick") else ""
    seeds = ",".join(str(x) for x in s.get("seeds", []))
    return (
        f"Command: `{s.get('command', '?')}`{mode} — seeds {seeds}, sigma_des "
        f"{s.get('version', '?')}."
    )


def plots_line(name: str, s: dict[str, Any], outputs: Path) -> str:
    """Where the plots are."""
    ps = s.get("plots", [])
    if not ps:
        return ""
    return "Plots: " + ", ".join(f"`{outputs.name}/{name}/{p}`" for p in ps) + "."


# ------------------------------------------------------------------ sections


def sec_scale_200(s: dict[str, Any]) -> str:
    """The 200-node study."""
    var = s["variants"]["default"]
    sc = var["scenario"]
    rows = []
    for lab in labels(var):
        rows.append(
            [
                lab,
                num(get(var, lab, "latency_state_mean"), 2),
                f"{num(get(var, lab, 'aoi_mean'), 2)} ± {num(get(var, lab, 'aoi_std'), 2)}",
                num(get(var, lab, "aoi_p99"), 1),
                num(get(var, lab, "buffer_bytes_peak") / 1024, 1),
                num(get(var, lab, "throughput_mbps"), 1),
                num(get(var, lab, "snapshot_rate_hz"), 1),
                num(get(var, lab, "trigger_rate_hz"), 1),
                num(get(var, lab, "spread_mean"), 2),
            ]
        )
    t = md_table(
        [
            "method",
            "state latency (ms)",
            "AoI mean ± std (ms)",
            "AoI p99 (ms)",
            "server buffer peak (KiB)",
            "throughput (Mbps)",
            "snapshots (Hz)",
            "triggers (Hz)",
            "frame spread",
        ],
        rows,
    )
    b = var["methods"].get("bides", {})
    ls = var["methods"].get("lockstep", {})
    h = var["methods"].get("hlc", {})
    return fill(
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
        for lab in labels(v):
            rows.append(
                [
                    lab if v_name == "default" else f"{lab} ({v_name.replace('_', ' ')})",
                    num(get(v, lab, "throughput_mbps"), 1),
                    f"{num(get(v, lab, 'aoi_mean'), 1)} ± {num(get(v, lab, 'aoi_std'), 1)}",
                    num(get(v, lab, "latency_state_mean"), 1),
                    num(100 * (get(v, lab, "broker_util") or math.nan), 0),
                    num(get(v, lab, "trigger_rate_hz"), 1),
                    num(get(v, lab, "f_trig_settled_hz"), 1),
                    num(get(v, lab, "snapshot_rate_hz"), 1),
                ]
            )
    t = md_table(
        [
            "method",
            "throughput (Mbps)",
            "AoI mean ± std (ms)",
            "state latency (ms)",
            "broker load (%)",
            "achieved triggers (Hz)",
            "f_trig in force, last quarter (Hz)",
            "snapshots (Hz)",
        ],
        rows,
    )
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
    return fill(
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


def sec_latency(s: dict[str, Any]) -> str:
    """The latency-tolerance study."""
    parts = []
    sc = None
    for v_name, var in s["variants"].items():
        sc = var["scenario"]
        rows = []
        for lab in labels(var):
            rows.append(
                [
                    lab,
                    f"{num(get(var, lab, 'aoi_mean'), 1)} ± {num(get(var, lab, 'aoi_std'), 1)}",
                    num(get(var, lab, "aoi_p99"), 0),
                    num(get(var, lab, "latency_state_mean"), 1),
                    f"{num(get(var, lab, 'displacement_mean_ms'), 0)} / "
                    f"{num(get(var, lab, 'displacement_max_ms'), 0)}",
                    f"{num(get(var, lab, 'pos_err_mean'), 3)} / "
                    f"{num(get(var, lab, 'pos_err_max'), 2)}",
                    num(get(var, lab, "snapshot_rate_hz"), 1),
                    num(get(var, lab, "aligned_rate_hz"), 1),
                    num(get(var, lab, "trigger_rate_hz"), 1),
                    f"{num(get(var, lab, 'filled_frac'), 2)} / "
                    f"{num(get(var, lab, 'extrapolated_frac'), 2)}",
                ]
            )
        parts.append(
            f"*{v_name} transport:*\n\n"
            + md_table(
                [
                    "method",
                    "AoI mean ± std (ms)",
                    "AoI p99 (ms)",
                    "state latency (ms)",
                    "displacement mean / max (ms)",
                    "position error mean / max (m)",
                    "snapshots (Hz)",
                    "aligned frames/s",
                    "triggers (Hz)",
                    "filled / extrapolated",
                ],
                rows,
            )
        )
    assert sc is not None
    d = s["variants"].get("datagram", next(iter(s["variants"].values())))
    st = s["variants"].get("stream")
    ratio = (get(d, "bides", "aoi_mean") or math.nan) / (get(d, "hlc", "aoi_mean") or math.nan)
    lat = sc["net"]["host_link"]["latency"]
    stream_txt = ""
    if st is not None:
        stream_txt = fill(
            "latency_tolerance_stream",
            sc=sc,
            st_none_latency_state_mean=num(get(st, "none", "latency_state_mean"), 0),
            st_lockstep_trigger_rate_hz=num(get(st, "lockstep", "trigger_rate_hz"), 1),
            st_bides_f_trig_settled_hz=num(get(st, "bides", "f_trig_settled_hz"), 0),
            st_bides_extrapolated_frac=num(get(st, "bides", "extrapolated_frac"), 2),
        )
    return fill(
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
    return fill(
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
    return fill(
        "faults",
        sc=sc,
        tgt_node=tgt.get("node"),
        tgt_host=tgt.get("host"),
        tgt_eviction_timeout_s=tgt.get("eviction_timeout_s"),
        tables=chr(10).join(p + chr(10) for p in parts),
    )


def sec_sweep(s: dict[str, Any]) -> str:
    """The node-count sweep (written by ``experiments/sweep_nodes.py``)."""
    figs = s.get("figures", {})
    out = [
        "**Paper.** Lock-step AoI 12 ms at 60 nodes → 62 ± 15 ms at 200, unstable beyond "
        "~100 nodes; BiDES AoI 8.7 ms at 200 and 19 ms at 1000 nodes."
    ]
    meta = []
    for k in ("nodes", "methods", "seeds", "duration_s", "runs"):
        if k in s:
            meta.append(f"{k} = {s[k]}")
    out.append("**Ours.** " + ", ".join(meta) + ".")
    if isinstance(figs, dict) and figs:
        # figures: {method: {N: {metric: {mean, ci95, n}}}}
        methods = sorted(figs, key=lambda m: ORDER.index(m) if m in ORDER else len(ORDER))
        ns = sorted({n for m in methods for n in figs[m]}, key=lambda x: float(x))
        metrics = sorted({k for m in methods for d in figs[m].values() for k in d})
        for metric in metrics:
            rows = []
            for n in ns:
                row = [str(n)]
                for m in methods:
                    cell = figs[m].get(n, {}).get(metric)
                    if isinstance(cell, dict):
                        row.append(f"{num(cell.get('mean'), 2)} ± {num(cell.get('ci95'), 2)}")
                    else:
                        row.append(num(cell, 2))
                rows.append(row)
            out.append(
                f"*{metric}* (mean ± 95 % CI over seeds):\n\n" + md_table(["N", *methods], rows)
            )
    if "lockstep_degrades_at" in s:
        where = s["lockstep_degrades_at"]
        rule = s.get("degrade_rule", "")
        out.append(
            f"Lock-Step degrades ({rule}): "
            + (f"N = {where}." if where is not None else "not within the grid.")
        )
    where = s.get("lockstep_degrades_at")
    verdict = (
        f"in our model it degrades from N = {where} on"
        if where is not None
        else "in our model it does not degrade within the grid"
    )
    out.append(
        "**Why they differ.** The sweep uses the same model as the scale studies (20 nodes "
        "per host, LAN latency, the default broker). Lock-Step's barrier costs one broker "
        "round trip per frame, which only becomes expensive when rounds get slow (a "
        f"saturating broker, loss, stragglers): {verdict}, whereas the paper's "
        "Gazebo/FastDDS baseline is unstable beyond ~100 nodes for reasons in its own "
        "transport stack (Lock-Step over our DDS model: the peer-architectures section)."
    )
    return "\n\n".join(out)


SECTIONS: dict[str, tuple[str, Callable[[dict[str, Any]], str]]] = {
    "scale_200": ("200 nodes: latency, AoI, memory, throughput, frame rate", sec_scale_200),
    "scale_1000": ("1000 nodes: throughput, AoI, adaptive trigger rate", sec_scale_1000),
    "latency_tolerance": ("Latency tolerance: 30 % loss, 30 ± 10 ms delay", sec_latency),
    "alignment_cost": ("Cost of the alignment step (Algorithm 1)", sec_cost),
    "faults": ("Faults: crash, straggler, degraded host", sec_faults),
    "sweep_nodes": ("Node-count sweep", sec_sweep),
}


def build(outputs: Path) -> str:
    """The whole report as Markdown."""
    head = fill("head", out=outputs.name)
    body = [head]
    for i, (name, (title, fn)) in enumerate(SECTIONS.items(), start=1):
        path = outputs / name / "summary.json"
        body.append(f"## {i}. {title} (`{name}`)\n")
        if not path.exists():
            if name == "sweep_nodes":
                body.append(
                    "Not run: `python experiments/sweep_nodes.py` writes "
                    f"`{outputs.name}/sweep_nodes/summary.json`.\n"
                )
            else:
                body.append(f"Not run yet: `python experiments/{name}.py`.\n")
            continue
        s = json.loads(path.read_text())
        try:
            text = fn(s)
        except (KeyError, TypeError, ValueError, StopIteration, AssertionError) as e:
            text = f"(could not read `{path}`: {type(e).__name__}: {e})"
        body.append(text + "\n")
        if name != "sweep_nodes":
            body.append(provenance(s) + " " + plots_line(name, s, outputs) + "\n")
        else:
            pngs = {"plots": sorted(p.name for p in path.parent.glob("*.png"))}
            body.append(
                "Command: `python experiments/sweep_nodes.py` (see [`SWEEPS.md`](SWEEPS.md)). "
                + plots_line(name, pngs, outputs)
                + "\n"
            )
    from report_interpolation import section as interpolation_section  # issue 12

    body.append(interpolation_section(outputs))
    from report_model_tuning import section as model_tuning_section

    body.append(model_tuning_section(outputs))
    from report_peer import section as peer_section

    body.append(peer_section(outputs))
    return "\n".join(body).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the report."""
    p = argparse.ArgumentParser(
        prog="experiments/make_report.py",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--outputs", type=Path, default=Path("out"), help="studies' output directory")
    p.add_argument(
        "--report", type=Path, default=ROOT / "docs" / "REPRODUCTION.md", help="report to write"
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 if the report would differ from --report",
    )
    a = p.parse_args(argv)
    text = build(a.outputs)
    if a.check:
        same = a.report.exists() and a.report.read_text() == text
        print(f"{a.report} is {'up to date' if same else 'OUT OF DATE'} for {a.outputs}")
        return 0 if same else 1
    a.report.parent.mkdir(parents=True, exist_ok=True)
    a.report.write_text(text)
    found = [n for n in SECTIONS if (a.outputs / n / "summary.json").exists()]
    print(f"wrote {a.report} ({len(found)} of {len(SECTIONS)} studies: {', '.join(found)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
