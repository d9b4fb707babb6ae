"""The held-out misses of a validation, each with what its data point at: ``misses.csv``.

One row per scored held-out cell x method x metric outside its band (the headline's
strict rule; trigger rates only where live held its rate, as scored): the DES and live
values, the live runs' spread and whether the DES lies inside their range, the DES's
regime, the live server's busy loop and the live processes' run-queue wait (cores,
from ``processes.csv``, means over the cell's runs), and a reading chosen by fixed
rules, the first that applies:

* ``live spread`` — the cell's live runs disagree by more than the band and the DES
  lies within their range: the miss is live's run-to-run variation;
* ``near capacity`` — the DES puts the cell near capacity (its regime:
  ``sigma_des.calibrate.intervals.regime``; a trigger-rate row's is the cell's and
  method's other rows', its own saying whether the DES holds the rate);
* ``live run queue`` — the DES is below live where live's processes waited on the
  run queue for at least :data:`RUNQ_BUSY` cores (runnable, no core free: processes
  outnumber cores), which the DES calls below capacity;
* ``loss`` / ``added latency`` — a cell with that impairment;
* ``small bundles`` — a bundled cell smaller than the calibration's, DES above live;
* ``below capacity`` — none of these.

The summary counts the readings by metric and direction (DES below or above live).
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from sigma_lab.studies.validation.scoring import BAND, PP_BAND, live_repeats

__all__ = ["MISS_COLUMNS", "RUNQ_BUSY", "miss_md", "miss_rows"]

#: Columns of ``misses.csv``.
MISS_COLUMNS = ("cell", "method", "metric", "des", "live", "error", "error_unit", "runs",
                "spread", "des_in_runs", "regime", "server_loop_busy", "runq_cores",
                "direction", "reading")

#: Run-queue cores (summed over a run's processes) from which a miss is read as the
#: live machine's scheduler holding the processes: on average one runnable process waits.
RUNQ_BUSY = 1.0
#: Metrics whose misses are read (the trigger rate's are where live held it: few).
_READ = ("aoi_mean", "aoi_p99", "latency_state_mean", "missed_frac", "trigger_rate_hz")


def _spread(r: dict[str, Any], runs: list[float]) -> float:
    """Max minus min of the live runs: relative to their mean, or in pp."""
    if len(runs) < 2:
        return math.nan
    if r["error_unit"] == "pp":
        return 100.0 * (max(runs) - min(runs))
    mean = sum(runs) / len(runs)
    return (max(runs) - min(runs)) / mean if mean > 0 else math.nan


def _load(procs: list[dict[str, Any]], cell: str, method: str) -> tuple[float, float]:
    """The live server's loop-busy cores and all processes' run-queue cores, means over
    the runs of ``cell`` (its copies ``cell-c2``...)."""
    busy: list[float] = []
    runq: dict[str, float] = {}
    for p in procs:
        c = str(p["cell"])
        if p["method"] != method or (c != cell and not c.startswith(cell + "-c")):
            continue
        n = float(p["processes"])
        q = float(p["runq_cores"])
        if math.isfinite(q):
            runq[c] = runq.get(c, 0.0) + q * n
        if p["kind"] == "server" and math.isfinite(float(p["loop_busy"])):
            busy.append(float(p["loop_busy"]))
    mean_busy = sum(busy) / len(busy) if busy else math.nan
    mean_runq = sum(runq.values()) / len(runq) if runq else math.nan
    return mean_busy, mean_runq


def _reading(r: dict[str, Any], spread: float, inside: bool, cal_nodes: int,
             runq: float) -> str:
    band = PP_BAND if r["error_unit"] == "pp" else BAND
    if math.isfinite(spread) and spread > band and inside:
        return "live spread"
    if str(r["regime"]).endswith("near"):
        return "near capacity"
    if math.isfinite(runq) and runq >= RUNQ_BUSY and r["des"] < r["live"]:
        return "live run queue"
    if r["impairment"] == "loss5":
        return "loss"
    if r["impairment"] == "lat5":
        return "added latency"
    if r["mode"] == "bundle" and int(r["nodes"]) < cal_nodes and r["des"] > r["live"]:
        return "small bundles"
    return "below capacity"


def miss_rows(rows: list[dict[str, Any]], procs: list[dict[str, Any]], cal_nodes: int
              ) -> list[dict[str, Any]]:
    """The held-out misses of ``rows`` (``cells.csv``'s) with their readings.

    Args:
        rows: the suite's cell rows.
        procs: ``processes.csv``'s rows (may be empty: the load columns are then NaN).
        cal_nodes: the calibration setting's node count.
    """
    machine = {(r["cell"], r["method"]): r["regime"] for r in rows
               if r["metric"] == "aoi_mean"}
    out = []
    for r in rows:
        if not r["held_out"] or r["within_band"] is not False or r["metric"] not in _READ \
                or r["passed"] == "":  # not scored (a trigger rate live did not hold)
            continue
        r = {**r, "regime": machine.get((r["cell"], r["method"]), r["regime"])}
        runs = live_repeats(r)
        spread = _spread(r, runs)
        inside = len(runs) >= 2 and min(runs) <= r["des"] <= max(runs)
        busy, runq = _load(procs, r["cell"], r["method"])
        out.append({"cell": r["cell"], "method": r["method"], "metric": r["metric"],
                    "des": r["des"], "live": r["live"], "error": r["rel_error"],
                    "error_unit": r["error_unit"], "runs": len(runs), "spread": spread,
                    "des_in_runs": inside, "regime": r["regime"], "server_loop_busy": busy,
                    "runq_cores": runq,
                    "direction": "below" if r["des"] < r["live"] else "above",
                    "reading": _reading(r, spread, inside, cal_nodes, runq)})
    return out


def _num(x: float, unit: str = "") -> str:
    return "-" if not math.isfinite(x) else f"{x:.3g}{unit}"


def miss_md(misses: list[dict[str, Any]]) -> list[str]:
    """The summary's section: counts by reading, then every miss."""
    lines = ["", "## Misses and what the data point at", ""]
    if not misses:
        return lines + ["No held-out cell missed its band."]
    count = Counter((m["reading"], m["metric"], m["direction"]) for m in misses)
    lines += [f"{len(misses)} held-out cell x method x metric values outside the band. "
              "By reading (rules in order: live's runs disagree by more than the band "
              "with the DES inside their range; the DES near capacity; live's run-queue "
              f"wait ≥ {RUNQ_BUSY:g} core with the DES below; an impairment; small bundles; "
              "else below capacity), metric and direction of the DES:", "",
              "| reading | metric | DES below live | DES above live |", "|---|---|---|---|"]
    for reading, metric in dict.fromkeys((k[0], k[1]) for k in sorted(count)):
        lines.append(f"| {reading} | {metric} | {count[(reading, metric, 'below')]} | "
                     f"{count[(reading, metric, 'above')]} |")
    lines += ["", "| cell | method | metric | DES | live (runs) | error | live spread | "
              "DES in runs | regime | server loop busy | run-queue cores | reading |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in misses:
        pp = m["error_unit"] == "pp"
        err = f"{m['error']:+.1f} pp" if pp else f"{100 * m['error']:+.0f} %"
        spread = _num(m["spread"], " pp") if pp else (
            "-" if not math.isfinite(m["spread"]) else f"{100 * m['spread']:.0f} %")
        lines.append(f"| {m['cell']} | {m['method']} | {m['metric']} | {_num(m['des'])} | "
                     f"{_num(m['live'])} ({m['runs']}) | {err} | {spread} | "
                     f"{'yes' if m['des_in_runs'] else 'no'} | {m['regime']} | "
                     f"{_num(m['server_loop_busy'])} | {_num(m['runq_cores'])} | "
                     f"{m['reading']} |")
    return lines
