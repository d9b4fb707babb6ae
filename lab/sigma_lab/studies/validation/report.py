"""The suite's outputs: ``cells.csv``, ``noise.csv``, ``knee.csv``, ``summary.md`` and the plot.

* ``cells.csv`` — tidy, one row per cell x method x metric: live (the mean of the
  cell's runs, each in ``live_runs``), DES, error (relative; percentage points for
  ``missed_frac``: see ``error_unit``), the live noise floor (of the cell's own runs,
  or with one run the calibration setting's: ``floor_source``), the verdict
  (``passed``, ``within_band``, ``rule``), the load (1-min load average, mean of
  before and after the live runs), the background CPU, ``under_load`` (any run),
  seed, the DES scenario's config hash, the live run's config hash and the version.
  The calibration run's own rows (the repeat it was fitted to, ``held_out`` False)
  are the out-of-suite in-sample check.
* ``noise.csv`` — the repeats of the calibration setting per method and metric and
  their noise floor.
* ``knee.csv`` — per message mode and method: live's knee (its grid), the DES's
  knee on its finer grid and on live's grid, the verdict, and each live repeat's own
  knee (:mod:`~.knees`).
* ``summary.md`` — shares per metric, the issue's targets ticked or not, the knee
  table, the in-sample errors and the cells.
* ``live_vs_des.png`` — DES against live per metric, with each metric's band;
  ``knee.png`` — missed frames against N, live and DES, the knees marked.
* ``processes.csv`` — per live cell, method and process kind: CPU, loop-busy and
  run-queue cores (:mod:`sigma_lab.studies.validation.processes`);
* ``coverage.csv`` and ``residuals.toml`` — the intervals' coverage on the held-out
  cells and their residuals (:mod:`sigma_lab.studies.validation.coverage`);
  ``misses.csv`` — every held-out miss and its reading (:mod:`~.misses`);
  ``rounds.csv`` — the round of a frame at each missed knee, live and DES, stage by
  stage (:mod:`~.rounds`); the knee itself: :mod:`~.knees`;
  ``loaded.csv`` — with ``--loaded-check``, a calibration under a CPU hog against an
  idle one, scored on the held-out cells (:mod:`~.loaded`).

A run is **under load** when the background CPU during its metrics window (other
processes' CPU, from its own CPU table) exceeds :data:`UNDER_LOAD` of the machine's
cores, or, without that table, when the 1-min load average before it exceeds the
core count.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Any

from sigma_des.calibrate.insample import apart_text, repeats_apart
from sigma_des.calibrate.intervals import (
    COVERAGE,
    RATE_METRIC,
    rate_regime,
    regime,
    residuals_toml,
)
from sigma_des.plotstyle import MIN_DPI, line_kw, metric_title
from sigma_des.tables import md_table
from sigma_lab.studies.validation.coverage import coverage_rows, residual_values
from sigma_lab.studies.validation.grid import Plan
from sigma_lab.studies.validation.kneeplot import knee_plot
from sigma_lab.studies.validation.knees import (
    copies,
    knee_grid,
    knee_points,
    knee_rows,
    live_of,
    point_names,
)
from sigma_lab.studies.validation.loaded import (
    LOADED_COLUMNS,
    loaded_md,
    loaded_rows,
    loaded_target,
)
from sigma_lab.studies.validation.misses import MISS_COLUMNS, miss_md, miss_rows
from sigma_lab.studies.validation.processes import PROCESS_COLUMNS, process_md, process_rows
from sigma_lab.studies.validation.rounds import ROUND_COLUMNS, round_md, round_rows
from sigma_lab.studies.validation.runs import UNDER_LOAD, des_scenario, load_calibration, under_load
from sigma_lab.studies.validation.scoring import (
    BAND,
    KNEE_MISSED,
    METRICS,
    PP_BAND,
    RATE_BAND,
    TARGETS,
    Verdict,
    error,
    judge,
    noise_floor,
    share,
)
from sigma_lab.studies.validation.suite import Outcome, des_key

__all__ = ["UNDER_LOAD", "cell_rows", "noise_rows", "under_load", "write_outputs"]

COLUMNS = ("cell", "mode", "nodes", "hosts", "impairment", "held_out", "method", "metric",
           "regime",
           "live", "des", "rel_error", "error_unit", "live_runs", "noise_floor", "floor_source",
           "passed", "within_band", "rule", "load", "background_cores", "under_load", "seed",
           "config_hash", "live_config_hash", "version")


def _repeats(plan: Plan, live: dict[str, dict[str, Any]], method: str, metric: str
             ) -> list[float]:
    return [float(live[c.name]["methods"].get(method, {}).get(metric, math.nan))
            for c in plan.cells if c.repeat and c.name in live]


def noise_rows(plan: Plan, live: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Per method and metric: the repeats of the calibration setting and the floor."""
    rows = []
    for m in plan.methods:
        for k in METRICS:
            xs = _repeats(plan, live, m, k)
            rows.append({"method": m, "metric": k, "repeats": " ".join(f"{x:.6g}" for x in xs),
                         "noise_floor": noise_floor(k, xs),
                         "unit": "pp" if k == "missed_frac" else "rel"})
    return rows


def cell_rows(plan: Plan, outcome: Outcome, f_trig: float,
              cores: int | None = None) -> list[dict[str, Any]]:
    """The tidy rows of ``cells.csv`` (see the module doc).

    A held-out cell that ran more than once is one row per method and metric: live is
    the mean of its runs, its noise floor their spread (``floor_source`` ``cell``), and
    where that exceeds 10 % the DES passes inside their range. A cell that ran once
    takes the calibration setting's floor (``floor_source`` ``calibration``). The
    calibration setting's row is the run the calibration was fitted to
    (``report["calibration_cell"]``; the first repeat if not said), its repeats' range.
    """
    live, des, report = outcome
    cores = cores or os.cpu_count() or 1
    floors = {(r["method"], r["metric"]): r["noise_floor"] for r in noise_rows(plan, live)}
    fitted = report.get("calibration_cell") or next(
        (c.name for c in plan.cells if c.repeat == 1), "")
    rows = []
    for cell in plan.cells:
        if (cell.repeat and cell.name != fitted) or cell.copy > 1 or cell.cal_extra \
                or cell.name not in live \
                or des_key(cell) not in des:
            continue
        runs = [live[cell.name]] if cell.repeat else copies(plan, live, cell.name)
        dv = des[des_key(cell)]
        load = sum(r["load_before"] + r["load_after"] for r in runs) / (2.0 * len(runs))
        for m in plan.methods:
            for k in METRICS:
                x, xs = live_of(runs, m, k)
                dm = dv["methods"][m]
                y = float(dm[k])
                own = len(runs) > 1
                reps = _repeats(plan, live, m, k) if cell.repeat else (xs if own else [])
                floor = noise_floor(k, xs) if own else floors[(m, k)]
                v = judge(k, x, y, floor, f_trig, reps)
                rows.append({
                    "cell": cell.name, "mode": cell.mode, "nodes": cell.nodes,
                    "hosts": cell.hosts, "impairment": cell.impairment,
                    "held_out": cell.held_out, "method": m, "metric": k,
                    "regime": _regime(k, cell.mode == "bundle", dm, f_trig), "live": x,
                    "des": y, "rel_error": error(k, x, y),
                    "error_unit": "pp" if k == "missed_frac" else "rel",
                    "live_runs": " ".join(f"{z:.6g}" for z in xs), "noise_floor": floor,
                    "floor_source": "cell" if own else "calibration",
                    "passed": v.ok if v.scored else "",
                    "within_band": v.within_band, "rule": v.rule, "load": load,
                    "background_cores": sum(r["background_cores"] for r in runs) / len(runs),
                    "under_load": any(under_load(r, cores) for r in runs), "seed": dv["seed"],
                    "config_hash": dv["config_hash"],
                    "live_config_hash": runs[0]["config_hash"], "version": dv["version"]})
    return rows


def _regime(metric: str, bundle: bool, dm: dict[str, Any], f_trig: float) -> str:
    """A row's regime as ``predict`` reads its figure in it: the DES's machine and missed
    frames, and for the trigger rate whether the DES holds it
    (:func:`~sigma_des.calibrate.intervals.rate_regime`)."""
    reg = regime(bundle, float(dm.get("machine_cpu_util_max", math.nan)),
                 float(dm.get("missed_frac", math.nan)))
    if metric == RATE_METRIC:
        return rate_regime(reg, float(dm.get(RATE_METRIC, math.nan)), f_trig)
    return reg


def _write_csv(path: Path, rows: list[dict[str, Any]], cols: tuple[str, ...] | None = None
               ) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(cols or (rows[0] if rows else ["empty"])))
        w.writeheader()
        w.writerows(rows)


def _fmt(k: str, x: float) -> str:
    if not math.isfinite(x):
        return "nan"
    return f"{100 * x:.1f} %" if k == "missed_frac" else f"{x:.3g}"


def _share_table(rows: list[dict[str, Any]]) -> tuple[list[str], list[bool]]:
    """Per metric: the strict share (the headline, the target's measure) and the passes
    with a cell's own live range."""
    head = ["metric", "band", "cells scored", "within the band (headline)",
            "passed with the cell's own live range", "target", "met"]
    out, ticks = [], []
    for k in METRICS:
        sel = [r for r in rows if r["held_out"] and r["metric"] == k]
        vs = [judge_row(r) for r in sel]
        n, ok, band = share(vs)
        frac = band / n if n else math.nan
        met = bool(n) and frac >= TARGETS[k]
        ticks.append(met)
        band_txt = {"trigger_rate_hz": f"±{RATE_BAND:.0%} where live holds its rate",
                    "missed_frac": f"±{PP_BAND:g} pp"}.get(k, f"±{BAND:.0%}")
        out.append([k, band_txt, str(n), f"{band} ({100 * frac:.0f} %)" if n else "-",
                    f"{ok}", f"≥ {TARGETS[k]:.0%}" if TARGETS[k] < 1 else "all",
                    "✔" if met else "✘"])
    return [md_table(head, out)], ticks


def _coverage_md(cov: list[dict[str, Any]]) -> list[str]:
    head = ["metric", "held-out cells", "inside the interval", "built for", "target",
            "median width"]
    body = [[c["metric"], str(c["cells"]),
             f"{c['covered']} ({100 * c['share']:.0f} %)" if c["cells"] else "-",
             f"{c['built_for']:.0%}", f"≥ {c['target']:.0%}",
             (f"{c['median_width']:.1f} pp" if c["width_unit"] == "pp"
              else f"{100 * c['median_width']:.2g} % of live")
             if math.isfinite(c["median_width"]) else "-"] for c in cov]
    return ["", "## Interval coverage (held-out cells, leave one out)", "",
            "Each held-out cell's interval is its DES value widened by the residuals of the "
            "other held-out cells of its metric and regime (as `sigma-des predict` widens "
            "by the validations' residuals; a trigger rate the DES does not hold among the "
            "rates not held), a missed-frame interval by at least one frame of the window "
            "either side and a trigger rate's by one trigger; covered when live's value is "
            "inside. Trigger rates live did not hold count here (not in the scores). The "
            "intervals "
            "are built for more than the target share: a regime has few residuals, and "
            "intervals built for exactly the target fall short of it about half the time.",
            "",
            md_table(head, body)]


def judge_row(r: dict[str, Any]) -> Verdict:
    """The verdict stored in a ``cells.csv`` row (scored = ``passed`` not empty)."""
    return Verdict(r["passed"] != "", bool(r["passed"]), bool(r["within_band"]), r["rule"])


def _apart(report: dict[str, Any]) -> str:
    """How many in-sample misses no calibration could avoid: their setting's live
    repeats more than 22 % apart (``repeats_apart``), on the scored metrics."""
    apart = [g for g in repeats_apart(report) if g["metric"] in METRICS]
    n = sum(g["flagged"] for g in apart)
    if not n:
        return ""
    where = "; ".join(apart_text(g) for g in apart)
    return (f"; {n} of the misses are runs of a setting whose own live repeats are more "
            f"than 22 % apart, so no one value is within 10 % of each: {where}")


def _knee_md(knees: list[dict[str, Any]]) -> list[str]:
    """The knee section of ``summary.md``."""
    lines: list[str] = []
    lines += ["", f"## Knee (the first N that does not hold: rate held, ≤ {KNEE_MISSED:.0%} "
              "of frames missed)", ""]
    lines.append("The predicate of `sigma-des capacity` on each grid, in order: capacity = "
                 "the last N that holds before the knee, knee = the first that does not.")
    lines.append("")
    lines.append("The verdict is on live's knee from the mean of each size's runs; beside "
                 "it, the knee each live repeat gives on its own, and whether the DES's knee "
                 "is within ±25 % of one of them (live's runs at a size disagree about "
                 "holding: live's own knee is uncertain there).")
    lines.append("")
    lines.append(md_table(["mode", "method", "live grid", "live capacity", "live knee",
                           "DES capacity", "DES knee", "DES knee on live grid",
                           "within ±25 %", "live repeats' knees", "within a repeat's"],
                          [[r["mode"], r["method"], r["live_grid"],
                            str(r["live_capacity"] or "-"), str(r["live_knee"] or "-"),
                            str(r["des_capacity"] or "-"), str(r["des_knee"] or "-"),
                            str(r["des_knee_on_live_grid"] or "-"),
                            r["verdict"], r["live_run_knees"],
                            "yes" if r["within_a_live_run"] else "no"] for r in knees]))
    return lines


def summary_md(plan: Plan, rows: list[dict[str, Any]], knees: list[dict[str, Any]],
               noise: list[dict[str, Any]], report: dict[str, Any], command: str,
               cov: list[dict[str, Any]] | None = None, more: tuple[str, ...] = ()) -> str:
    """``summary.md`` (see the module doc); ``more``: further lines of its target list."""
    loads = [r["load"] for r in rows if r["metric"] == METRICS[0]]
    held = [r for r in rows if r["held_out"] and r["metric"] == METRICS[0]]
    lines = ["# Live vs DES validation", "", f"`{command}`", "",
             f"{len(plan.cells)} live cells, methods {', '.join(plan.methods)}, "
             f"{plan.duration:g} s runs (warmup {plan.warmup:g} s). Load (1-min average) "
             f"{min(loads, default=math.nan):.1f}–{max(loads, default=math.nan):.1f}; "
             f"{sum(bool(r['under_load']) for r in held)} of {len(held)} held-out "
             f"cell x method runs under load (background CPU > {UNDER_LOAD:.0%} of the cores).",
             "", "## Shares of held-out cells", ""]
    table, ticks = _share_table(rows)
    lines += table
    by_range = sum(r["held_out"] and r["rule"] == "live range" and r["passed"] is True
                   for r in rows)
    wide = [r for r in noise if math.isfinite(r["noise_floor"]) and r["unit"] == "rel"
            and r["noise_floor"] > 0.5]
    copies = sum(r["held_out"] and r["floor_source"] == "cell" for r in rows
                 if r["metric"] == METRICS[0])
    fitted = report.get("calibration_cell") or "cal-r1"
    used = ", ".join(c for c in report.get("calibration_cells") or [] if c) or fitted
    lines += ["", f"The headline is the strict share: within the band of the mean of the "
              f"cell's live runs. {by_range} more passes are by the live-range rule (live "
              "did not reproduce itself within 10 %: the DES inside the range of the cell's "
              f"own runs, at least two). {copies} of {len(held)} held-out cell x method "
              f"pairs ran more than once (live = the mean of the runs). Calibrated on {used} "
              f"({fitted} first: the most typical run of the calibration setting)."]
    if copies < len(held):
        lines.append(f"**{len(held) - copies} of {len(held)} held-out cell x method pairs ran "
                     "once**: their live value is one run, not the mean of at least two the "
                     "headline asks for (run with --cell-repeats 2).")
    if wide:
        lines.append(f"**Live did not reproduce itself**: the noise floor exceeds 50 % for "
                     f"{len(wide)} of {sum(r['unit'] == 'rel' for r in noise)} method x "
                     "metric pairs, which makes the live-range rule nearly vacuous: rerun "
                     "on an idle machine.")
    quiet = [r for r in rows if not r["under_load"]]
    if len(quiet) != len(rows):
        lines += ["", "Cells not under load only:", ""] + _share_table(quiet)[0]
    lines += _knee_md(knees)
    knee_ok = {mode: all(r["verdict"] == "met" for r in knees if r["mode"] == mode)
               and any(r["mode"] == mode for r in knees) for mode in ("node", "bundle")}
    ins = [r for r in report.get("in_sample", []) if math.isfinite(r.get("error", math.nan))
           and r["metric"] in METRICS]
    ins_ok = bool(ins) and not any(r["flagged"] for r in ins)
    lines += ["", "## Targets", ""]
    names = ["≥ 80 % mean AoI", "≥ 80 % p99 AoI", "≥ 80 % mean state latency",
             "trigger rate within 5 % where live holds it", "missed frames within 10 pp"]
    order = [METRICS.index(k) for k in ("aoi_mean", "aoi_p99", "latency_state_mean",
                                        "trigger_rate_hz", "missed_frac")]
    lines += [f"- [{'x' if ticks[i] else ' '}] {n}" for n, i in zip(names, order, strict=True)]
    lines += [f"- [{'x' if knee_ok[m] else ' '}] knee within ±25 % ({m} messages)"
              for m in ("node", "bundle")]
    lines += [f"- [{'x' if ins_ok else ' '}] in-sample error ≤ 10 % on every metric "
              f"({sum(not r['flagged'] for r in ins)} of {len(ins)} cells{_apart(report)})",
              *more]
    if cov:
        lines += _coverage_md(cov)
    lines += ["", "## Live noise floor (calibration setting, repeats)", "",
              md_table(["method", "metric", "repeats", "floor"],
                       [[r["method"], r["metric"], r["repeats"],
                         (f"{r['noise_floor']:.1f} pp" if r["unit"] == "pp"
                          else f"{100 * r['noise_floor']:.0f} %")
                         if math.isfinite(r["noise_floor"]) else "nan"] for r in noise])]
    lines += ["", "## Cells (live / DES, error; floor in brackets)", ""]
    lines.append(md_table(["cell", "method", "load", *METRICS], _cell_table(rows)))
    lines += ["", "Warnings of the calibration:", ""]
    lines += [f"- {w}" for w in report.get("warnings", [])] or ["- none"]
    return "\n".join(lines) + "\n"


def _cell_table(rows: list[dict[str, Any]]) -> list[list[str]]:
    out = []
    keys = list(dict.fromkeys((r["cell"], r["method"]) for r in rows))
    for cell, m in keys:
        sel = {r["metric"]: r for r in rows if r["cell"] == cell and r["method"] == m}
        first = sel[METRICS[0]]
        txt = []
        for k in METRICS:
            r = sel[k]
            e, f = r["rel_error"], r["noise_floor"]
            unit = "pp" if k == "missed_frac" else "%"
            scale = 1.0 if k == "missed_frac" else 100.0
            mark = "" if r["passed"] == "" else (" ✔" if r["passed"] else " ✘")
            txt.append(f"{_fmt(k, r['live'])} / {_fmt(k, r['des'])} "
                       f"({scale * e:+.0f} {unit}{mark}; {scale * f:.0f})"
                       if math.isfinite(e) else f"{_fmt(k, r['live'])} / {_fmt(k, r['des'])}{mark}")
        load = f"{first['load']:.1f}" + (" *" if first["under_load"] else "")
        out.append([cell + ("" if first["held_out"] else " (in-sample)"), m, load, *txt])
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """DES against live, one panel per metric, with the metric's band; runs under load
    hollow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, grid = plt.subplots(2, 3, figsize=(13, 8.5), layout="constrained")
    axes = list(grid.flat)
    for ax, k in zip(axes, METRICS, strict=False):
        sel = [r for r in rows if r["metric"] == k and math.isfinite(r["live"])
               and math.isfinite(r["des"])]
        scale = 100.0 if k == "missed_frac" else 1.0
        seen: set[str] = set()
        for r in sel:
            kw = line_kw(r["method"], n_points=1)
            ax.scatter(scale * r["live"], scale * r["des"], marker=kw["marker"], s=36,
                       edgecolors=kw["color"],
                       facecolors="none" if r["under_load"] else kw["color"],
                       label=None if r["method"] in seen else r["method"])
            seen.add(r["method"])
        vals = [scale * v for r in sel for v in (r["live"], r["des"])]
        _band(ax, k, [v for v in vals if v > 0])
        unit = "%" if k == "missed_frac" else ("Hz" if k == "trigger_rate_hz" else "ms")
        ax.set_xlabel(f"live ({unit})")
        ax.set_ylabel(f"DES ({unit})")
    handles, labels = axes[0].get_legend_handles_labels()
    axes[-1].axis("off")
    axes[-1].legend(handles, labels, loc="center", title="filled: idle; hollow: under load")
    fig.savefig(path, dpi=max(MIN_DPI, 110))
    plt.close(fig)


def _band(ax: Any, k: str, vals: list[float]) -> None:
    """The diagonal and the metric's band; AoI and latency on log axes (they span
    decades between an idle cell and a collapsed one)."""
    if k == "missed_frac":
        hi = max(vals + [1.0]) * 1.05
        ax.fill_between([0, hi], [-PP_BAND, hi - PP_BAND], [PP_BAND, hi + PP_BAND],
                        color="0.9", zorder=0)
        lo, title = 0.0, f"±{PP_BAND:g} pp"
    elif k == "trigger_rate_hz":
        hi = max(vals + [1.0]) * 1.05
        ax.fill_between([0, hi], [0, (1 - RATE_BAND) * hi], [0, (1 + RATE_BAND) * hi],
                        color="0.9", zorder=0)
        lo, title = 0.0, f"±{RATE_BAND:.0%}"
    else:
        lo, hi = min(vals or [1.0]) / 1.3, max(vals or [1.0]) * 1.3
        ax.set_xscale("log")
        ax.set_yscale("log")
        xs = [lo * (hi / lo) ** (i / 40) for i in range(41)]
        ax.fill_between(xs, [(1 - BAND) * x for x in xs], [(1 + BAND) * x for x in xs],
                        color="0.9", zorder=0)
        title = f"±{BAND:.0%}"
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.8)
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_title(f"{metric_title(k)} (band {title})", fontsize=9)


def _rounds(plan: Plan, outcome: Outcome, knees: list[dict[str, Any]], out: Path
            ) -> list[dict[str, Any]]:
    """``rounds.csv``'s rows (:mod:`~sigma_lab.studies.validation.rounds`): none without
    a missed knee, or without a calibration in ``out/cal`` (the section says so)."""
    if not any(k["verdict"] == "missed" for k in knees) \
            or not (out / "cal" / "calibrated.toml").exists():
        return []
    live = outcome[0]
    cal, report = load_calibration(out / "cal")
    points = {mode: knee_grid(plan, live, mode) for mode in ("node", "bundle")}
    return round_rows(plan, knees, points, lambda c: point_names(plan, live, c),
                      lambda c: des_scenario(cal, report, c, plan, out / "cells" / "samples"),
                      out)


def write_outputs(plan: Plan, outcome: Outcome, out: Path, f_trig: float, command: str
                  ) -> list[dict[str, Any]]:
    """Write every output file into ``out``; the ``cells.csv`` rows."""
    rows = cell_rows(plan, outcome, f_trig)
    noise = noise_rows(plan, outcome[0])
    knees = knee_rows(plan, outcome, f_trig)
    cov = coverage_rows(rows, METRICS, frames=f_trig * (plan.duration - plan.warmup),
                        window=plan.duration - plan.warmup, f_trig=f_trig)
    _write_csv(out / "coverage.csv", cov)
    (out / "residuals.toml").write_text(residuals_toml(
        residual_values(rows), {"coverage": COVERAGE,
                                "kind": "per-cell residuals of held-out cells",
                                "source": command}))
    _write_csv(out / "cells.csv", rows, COLUMNS)
    _write_csv(out / "noise.csv", noise)
    _write_csv(out / "knee.csv", knees)
    procs = process_rows(out / "live", list(outcome[0]))  # every run: knee runs too
    if procs:
        _write_csv(out / "processes.csv", procs, PROCESS_COLUMNS)
    misses = miss_rows(rows, procs, plan.cal_nodes)
    _write_csv(out / "misses.csv", misses, MISS_COLUMNS)
    cores = os.cpu_count() or 1
    loaded = loaded_rows(rows, out, cores, f_trig)
    target = loaded_target(loaded, cores)
    text = summary_md(plan, rows, knees, noise, outcome[2], command, cov,
                      () if target is None else (target,))
    text += "\n".join(miss_md(misses)) + "\n"
    if loaded:
        _write_csv(out / "loaded.csv", loaded, LOADED_COLUMNS)
        text += "\n".join(loaded_md(loaded, cores)) + "\n"
    rounds = _rounds(plan, outcome, knees, out)
    _write_csv(out / "rounds.csv", rounds, ROUND_COLUMNS)
    text += "\n".join(round_md(rounds, any(k["verdict"] == "missed" for k in knees))) + "\n"
    if procs:
        text += ("\n## Live processes (cores per second of the window, means over the "
                 "methods; a host is the mean of the run's hosts)\n\n"
                 + "\n".join(process_md(procs)) + "\n")
    (out / "summary.md").write_text(text)
    plot(rows, out / "live_vs_des.png")
    knee_plot(knee_points(plan, outcome), knees, KNEE_MISSED, out / "knee.png")
    return rows

