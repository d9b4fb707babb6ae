"""The engine benchmark's printed tables (speed, speed-up, metric checks, cohort vs baseline)."""

from __future__ import annotations

from typing import Any

from sigma_des.tables import cell, text_table
from sigma_lab.studies.engine_bench import BASELINE_RTOL, COMPARED, Check, col
from sigma_lab.studies.engine_events import class_table

__all__ = ["check_table", "metric_table", "report_text", "speed_table", "speedup_table"]


def _num(x: Any, spec: str) -> str:
    """``cell`` with NaN (not measured, e.g. no reference) shown as ``-``."""
    return "-" if isinstance(x, float) and x != x else cell(x, spec)


def _target(r: dict[str, Any]) -> str:
    t = r["target_x"]
    return f">= {t:g}x" if t == t else "-"


def _met(r: dict[str, Any]) -> str:
    t, x = r["target_x"], r["x_realtime_norm"]
    if t != t or x != x:
        return "-"
    return "yes" if x >= t else "no"


def speed_table(rows: list[dict[str, Any]]) -> str:
    """One line per case (cohort twins marked ``cohort~``, the reference baseline ``ref``)."""
    head = [
        "N",
        "scenario",
        "method",
        "impl",
        "engine used",
        "sim s",
        "s/s",
        "xRT",
        "cpu s/s",
        "xRT cpu",
        "load",
        "xRT norm",
        "target",
        "met",
        "ev/s",
        "batched",
        "RSS MB",
    ]
    lines = [head]
    for r in rows:
        lines.append(
            [
                str(r["n"]),
                r["scenario"],
                r["method"],
                r["impl"] + {"twin": "~", "reference": " ref"}.get(r["role"], ""),
                r["engine_used"],
                cell(r["sim_s"], "g"),
                cell(r["wall_per_sim_s"], ".3f"),
                cell(r["x_realtime"], ".2f"),
                cell(r["cpu_per_sim_s"], ".3f"),
                cell(r["x_realtime_cpu"], ".2f"),
                cell(r["load1"], ".1f"),
                _num(r["x_realtime_norm"], ".2f"),
                _target(r),
                _met(r),
                cell(r["events_per_s"], ",.0f"),
                cell(r["batched_share"], ".1%"),
                cell(r["peak_rss_mb"], ".0f"),
            ]
        )
    return text_table(lines)


def speedup_table(rows: list[dict[str, Any]]) -> str:
    """One line per (N, scenario, method): cohort/events, cohort/baseline, events/baseline.

    ``cohort ran as`` is the engine the cohort case really used (``events`` after a
    fallback, where cohort/events compares the per-message engine with itself).
    """
    lines = [
        [
            "N",
            "scenario",
            "method",
            "cohort ran as",
            "cohort/events",
            "cohort/baseline",
            "events/baseline",
            "cohort/baseline cpu",
            "target",
        ]
    ]
    for r in rows:
        if r["impl"] != "cohort" or r["role"] != "main":
            continue
        ev = next(
            (
                x
                for x in rows
                if (x["n"], x["method"], x["scenario"], x["impl"], x["role"])
                == (r["n"], r["method"], r["scenario"], "events", "main")
            ),
            None,
        )
        lines.append(
            [
                str(r["n"]),
                r["scenario"],
                r["method"],
                r["engine_used"],
                cell(r["ratio_vs_events"], ".2f"),
                cell(r["ratio_vs_baseline"], ".2f"),
                cell(ev["ratio_vs_baseline"] if ev else "", ".2f"),
                cell(_cpu_ratio(rows, r), ".1f"),
                ">= 300x" if r["scenario"] == "restricted" and r["ratio_vs_baseline"] != ""
                else "-",
            ]
        )
    return text_table(lines)


def _cpu_ratio(rows: list[dict[str, Any]], r: dict[str, Any]) -> float | str:
    """Baseline CPU-s/s over this cohort row's (same N, method, scenario); "" if none."""
    for b in rows:
        if (b["impl"], b["role"], b["n"], b["method"], b["scenario"]) == (
            "baseline", "main", r["n"], r["method"], r["scenario"]
        ):
            return float(b["cpu_per_sim_s"]) / float(r["cpu_per_sim_s"])
    return ""


def check_table(checks: list[Check]) -> str:
    """One line per metric comparison."""
    lines = [["N", "scenario", "method", "compared", "sim s", "max rel diff", "in", "verdict"]]
    for c in checks:
        if c.other == "events":
            verdict = "identical" if c.ok else "DIFFERENT"
        else:
            verdict = f"<= {BASELINE_RTOL:.0e}" if c.ok else f"DIFFERENT (> {BASELINE_RTOL:.0e})"
        lines.append(
            [
                str(c.n),
                c.scenario,
                c.method,
                f"cohort vs {c.other}",
                f"{c.sim_s:g}",
                f"{c.diff:.1e}",
                c.metric or "-",
                verdict,
            ]
        )
    return text_table(lines)


def metric_table(rows: list[dict[str, Any]]) -> str:
    """One line per N: cohort (method none) vs baseline on the restricted scenario."""
    pairs: list[tuple[dict[str, Any], dict[str, Any]]] = []
    for b in rows:
        if b["impl"] != "baseline" or b["role"] == "reference":
            continue
        for c in rows:
            if (c["impl"], c["scenario"], c["n"], c["sim_s"]) == (
                "cohort",
                "restricted",
                b["n"],
                b["sim_s"],
            ):
                pairs.append((c, b))
                break
    show = (
        "latency_state_mean",
        "latency_state_p99",
        "aoi_mean",
        "trigger_rate_hz",
        "throughput_mbps",
    )
    head = ["N", "sim s"]
    for name in show:
        head += [f"{name} cohort", "base"]
    head += ["max rel diff", "in"]
    lines = [head]
    for c, b in pairs:
        line = [str(b["n"]), f"{b['sim_s']:g}"]
        for name in show:
            key = col(name, dict(COMPARED)[name])
            line += [f"{c[key]:.6f}", f"{b[key]:.6f}"]
        line += [f"{b['max_rel_diff']:.1e}", b["max_rel_diff_metric"] or "-"]
        lines.append(line)
    return text_table(lines)


def report_text(rows: list[dict[str, Any]], checks: list[Check], notes: list[str]) -> str:
    """The report after the last case: speed, speed-up, metric-check and (when a
    baseline ran) cohort-vs-baseline tables with their captions, then one line per note.

    It starts with an empty line (it follows the progress lines).
    """
    out = [
        "",
        "Speed (s/s = wall seconds per simulated second, xRT = times real time, "
        "ev/s = events per wall second;",
        "full = commands on; restricted = commands off, the baseline's scenario class; "
        "cohort~ = cohort twin at a capped duration;",
        "load = 1-min load average at the case's end; xRT norm = times real time by CPU, "
        "normalised by the reference baseline (note below); target = the issue's, on that "
        "normalised figure)",
        speed_table(rows),
        "",
        "Speed-up (ratio of wall seconds per simulated second; - = not measured)",
        speedup_table(rows),
        "",
        "Metric checks (same simulated duration; cohort vs events: every metric, must be "
        f"identical; cohort vs baseline: {len(COMPARED)} metrics, rel. diff <= "
        f"{BASELINE_RTOL:.0e})",
        check_table(checks),
    ]
    if any(r["impl"] == "baseline" for r in rows):
        out += [
            "",
            "Metrics, cohort vs baseline (method none, restricted scenario, same seed;"
            " ms, Hz, Mbps)",
            metric_table(rows),
        ]
    if any(r.get("_classes") for r in rows):
        out += ["", "Compiled core's events by class (batched = run from fan-out batches or "
                    "channels), and per case the events queued one by one where batching was on",
                class_table(rows)]
    out += [f"note: {note}" for note in notes]
    return "\n".join(out)
