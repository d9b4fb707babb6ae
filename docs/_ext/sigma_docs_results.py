"""The result pages (validation, performance, learning), generated from ``docs/results/data/``.

Each folder ``docs/results/data/<name>/`` holds one study's committed outputs, filed by
``python experiments/make_docs_results.py``: its ``run.json`` (title, page, date,
machine, load, command, scale), its tables (CSV), summary (Markdown), plots (PNG) and
what it printed (``stdout.txt``). A page lists its studies in folder order; nothing on
it is written by hand. The validation page also tabulates every validation kept in
``validations-previous.csv`` beside the filed one (:func:`history_section`).
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from typing import Any

__all__ = ["BANDS", "PAGES", "PREVIOUS", "history_section", "results_page"]

#: page name -> (title, introduction)
PAGES = {
    "validation": ("Validation", "How well the calibrated DES predicts live runs on a real "
                   "Mosquitto broker. Every figure below was produced by the command shown "
                   "with it, on the machine and at the load shown; the tables and plots are "
                   "the command's own output files."),
    "performance": ("Performance", "What the simulator costs: engine speed, the learning "
                    "environment's speed and the cost per run. Timings depend on the machine "
                    "and its load (both shown with each study); the tables are the "
                    "benchmark scripts' own output files."),
    "learning": ("Learning", "What a policy learns on the aligned, delayed view the "
                 "environment gives: the training-under-delay studies' tables, learning "
                 "curves and held-out evaluations, from their own output files."),
}
#: CSV files longer than this are shown in part (the whole file is a download).
MAX_ROWS = 40
#: The earlier validations' held-out rows, each rescored by the model filed with the
#: validation study (``sigma_lab.studies.validation.cross``), under ``data/``.
PREVIOUS = "validations-previous.csv"
#: The held-out shares of the history table and their bands (relative; missed frames
#: in percentage points), as the validation suite scores them.
BANDS = {"aoi_mean": ("mean AoI", 0.15), "aoi_p99": ("p99 AoI", 0.15),
         "latency_state_mean": ("mean state latency", 0.15),
         "missed_frac": ("missed frames", 10.0)}


def _cell(v: str) -> str:
    return v.replace("|", "\\|").strip()


def csv_table(path: Path) -> list[str]:
    """A CSV file as a Markdown table (its first :data:`MAX_ROWS` rows)."""
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        return ["(empty)"]
    head, body = rows[0], rows[1:]
    out = ["| " + " | ".join(_cell(h) for h in head) + " |",
           "| " + " | ".join("---" for _ in head) + " |"]
    out += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in body[:MAX_ROWS]]
    if len(body) > MAX_ROWS:
        out += ["", f"*First {MAX_ROWS} of {len(body)} rows; the whole table is the "
                "download above.*"]
    return out


def _demote(md: str, levels: int) -> str:
    """A Markdown text with its headings moved ``levels`` down (to nest in a section)."""
    return re.sub(r"^(#+) ", lambda m: "#" * min(6, len(m.group(1)) + levels) + " ", md,
                  flags=re.M)


def _resumed(run: dict[str, Any]) -> str:
    """What a resumed run's wall time leaves out: the live runs it kept."""
    kept = run.get("live_runs_kept", 0)
    if not kept:
        return ""
    return (f" (resumed: {kept} live runs kept from an earlier invocation, "
            f"{run.get('live_runs_new', 0)} new)")


def _facts(run: dict[str, Any]) -> list[str]:
    m = run.get("machine", {})
    load = (f"{' / '.join(map(str, run['load_before']))} before, "
            f"{' / '.join(map(str, run['load_after']))} after (1, 5, 15 min)")
    return ["| Run | |", "| --- | --- |",
            f"| Date | {run['date']} |",
            f"| Command | `{run['command']}` |",
            f"| Scale | {run['scale']} |",
            f"| Machine | {m.get('cpu', '?')}, {m.get('cores', '?')} cores, "
            f"{m.get('memory_gb', '?')} GB, {m.get('system', '?')}, "
            f"Python {m.get('python', '?')} |",
            f"| Load average | {load} |",
            f"| Wall time | {run['wall_s']} s{_resumed(run)} |",
            f"| Version | sigma_des {run['version']} (commit {run.get('commit') or '?'}) |"]


def study_section(folder: Path, rel: str) -> list[str]:
    """One study's section: facts, summary, plots, tables and printed output."""
    run = json.loads((folder / "run.json").read_text())
    out = [f"## {run['title']}", "", run.get("about", ""), ""]
    if "quick" in run["scale"] or "small" in run["scale"]:
        out += [":::{note}", f"A small-scale run, made on {run['date'][:10]}: the "
                "figures show what the study reports, not its full-size result. "
                "Regenerate with `python experiments/make_docs_results.py`.", ":::", ""]
    cores = run.get("machine", {}).get("cores") or 0
    peak = max(run["load_before"][0], run["load_after"][0])
    if cores and peak > cores:
        out += [":::{warning}", f"The machine was overloaded during this run (1-minute "
                f"load average up to {peak:g} on {cores} cores): timings and live "
                "figures are distorted by the other work and are not representative.",
                ":::", ""]
    out += [*_facts(run), ""]
    summary = folder / "summary.md"
    if summary.exists():
        out += ["```{include} " + f"{rel}/summary.md",
                ":heading-offset: 2", "```", ""]
    for png in sorted(folder.glob("*.png")):
        out += [f"```{{figure}} {rel}/{png.name}", ":width: 100%", "", png.stem, "```", ""]
    for table in sorted(folder.glob("*.csv")):
        out += [f"### `{table.name}`", "", f"{{download}}`Download {table.name} "
                f"<{rel}/{table.name}>`", "", *csv_table(table), ""]
    for js in sorted(p for p in folder.glob("*.json") if p.name != "run.json"):
        out += [f"### `{js.name}`", "", f"{{download}}`Download {js.name} <{rel}/{js.name}>`",
                ""]
    printed = folder / "stdout.txt"
    if printed.exists() and printed.read_text().strip():
        out += ["### What the command printed", "", "```text",
                printed.read_text().rstrip(), "```", ""]
    return out


def _shares(rows: list[dict[str, str]]) -> list[str]:
    """Per :data:`BANDS` metric: ``k of n (p %)`` of ``rows`` within the band."""
    out = []
    for metric, (_, band) in BANDS.items():
        errs = [float(r["rel_error"]) for r in rows if r["metric"] == metric]
        errs = [e for e in errs if e == e]  # a NaN error (live 0) is not scored
        k = sum(abs(e) <= band for e in errs)
        out.append(f"{k} of {len(errs)} ({100 * k / len(errs):.0f} %)" if errs else "–")
    return out


def history_section(data: Path) -> list[str]:
    """Every validation's held-out shares, the earlier ones (:data:`PREVIOUS`, as the
    current model scores their live runs) and the filed one (``validation/cells.csv``);
    nothing without the earlier table."""
    prev = data / PREVIOUS
    filed = data / "validation" / "cells.csv"
    if not prev.exists():
        return []
    with prev.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    tags = list(dict.fromkeys(r["validation"] for r in rows))
    head = ["validation", *(f"{name} (±{band:g} pp)" if metric == "missed_frac" else
                            f"{name} (±{100 * band:g} %)"
                            for metric, (name, band) in BANDS.items())]
    table = [head, ["---"] * len(head)]
    for tag in tags:
        table.append([tag, *_shares([r for r in rows if r["validation"] == tag])])
    if filed.exists():
        with filed.open(newline="") as fh:
            held = [r for r in csv.DictReader(fh) if r["held_out"] == "True"]
        table.append(["the filed run (above)", *_shares(held)])
    return ["## Every validation, scored by the current model", "",
            "Each earlier validation's calibration runs calibrated again and its held-out "
            "cells predicted again by the model filed above, against the same live runs; "
            "a cell is within the band when the DES is within it of the mean of the "
            "cell's live runs. The spread between rows is the machine's from session to "
            "session as much as the model's.", "",
            *("| " + " | ".join(r) + " |" for r in table), "",
            f"{{download}}`Download {PREVIOUS} <data/{PREVIOUS}>`", ""]


def results_page(page: str, data: Path) -> str:
    """The page ``page`` as MyST Markdown, from the study folders under ``data``."""
    title, intro = PAGES[page]
    out = [f"# {title}", "", intro, ""]
    folders = [d for d in sorted(data.glob("*")) if (d / "run.json").exists()
               and json.loads((d / "run.json").read_text()).get("page") == page]
    if not folders:
        out += ["No study has been filed for this page yet: run "
                "`python experiments/make_docs_results.py`.", ""]
    for d in folders:
        out += study_section(d, f"data/{d.name}")
    if page == "validation":
        out += history_section(data)
    return "\n".join(out)
