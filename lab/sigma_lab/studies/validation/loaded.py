"""A calibration made under load, against one made on an idle machine.

The target: a calibration run made while a CPU hog is busy on one core either predicts
an idle machine's held-out cells within the same bands as an idle calibration, or is
refused. ``--loaded-check`` runs the calibration setting once more with :class:`Hog`
beside it (``loaded/hog/cal-hog``), calibrates on that run alone and, as the reference, on
the quietest repeat of the calibration setting alone (the same one-run recipe; the
least background CPU, :func:`quietest`), and predicts the held-out cells from each
(``loaded/<idle|hog>/des.json``; :func:`run_loaded`).
:func:`loaded_rows` scores both predictions with the headline's rule against the live
values of ``cells.csv`` and says whether ``sigma-des predict`` refuses the calibration
(:func:`~sigma_des.calibrate.campaign.loaded_runs`); ``loaded.csv`` and a section of
``summary.md`` (:func:`loaded_md`) come from them. Everything is kept: a rerun reuses
the run, the calibrations and the predictions.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from types import TracebackType
from typing import Any

from sigma_des.calibrate.campaign import UNDER_LOAD, loaded_runs
from sigma_des.errors import ConfigError
from sigma_des.tables import md_table
from sigma_lab.studies.validation.grid import Plan
from sigma_lab.studies.validation.runs import (
    background_cores,
    calibrate_run,
    des_cell,
    live_cell,
    live_timeout,
    load_calibration,
    read_json,
)
from sigma_lab.studies.validation.scoring import METRICS, judge, live_repeats

__all__ = ["HOG", "HOG_RUN", "IDLE", "LOADED_COLUMNS", "Hog", "loaded_md", "loaded_rows",
           "loaded_target", "quietest", "run_loaded"]

#: The two calibrations (folders of ``out/loaded``), and the loaded run's name.
IDLE, HOG, HOG_RUN = "idle", "hog", "cal-hog"
#: ``loaded.csv``'s columns: one row per calibration and metric.
LOADED_COLUMNS = ("calibration", "run", "background_cores", "refused", "metric", "within",
                  "scored")
#: The hog: a spin loop that ends by itself after ``argv[1]`` seconds.
_SPIN = ("import sys, time\nend = time.monotonic() + float(sys.argv[1])\n"
         "while time.monotonic() < end:\n    pass\n")


class Hog:
    """A process busy on one core (a spin loop) while the ``with`` block runs.

    Args:
        limit: seconds after which the spin loop stops by itself, should the block's
            end never come (a killed parent): the hog is bounded either way.
    """

    def __init__(self, limit: float) -> None:
        self.limit = limit
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> Hog:
        self.proc = subprocess.Popen([sys.executable, "-c", _SPIN, f"{self.limit:g}"],
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(timeout=10)


def quietest(plan: Plan, out: Path) -> str:
    """The repeat of the calibration setting whose live run had the least background CPU
    (the first on ties, or without the figure): the idle reference."""
    reps = [c.name for c in plan.cells if c.repeat >= 1 and c.mode == "node"
            and (out / "live" / c.name / "summary.json").exists()]
    if not reps:
        raise ConfigError("--loaded-check", f"no run of the calibration setting in {out}")

    def bg(name: str) -> float:
        b = background_cores(read_json(out / "live" / name / "summary.json") or {})
        return b if math.isfinite(b) else math.inf

    return min(reps, key=lambda n: (bg(n), reps.index(n)))


def _calibrated_on(d: Path) -> str:
    """The name of the run the calibration in ``d/cal`` was made on ("" if none)."""
    report = read_json(d / "cal" / "calibrated.json") or {}
    return ", ".join(Path(str(k)).name for k in report.get("background_cores_of_runs") or {})


def run_loaded(plan: Plan, out: Path, say: Callable[[str], None] = print) -> None:
    """The loaded run, both one-run calibrations and their predictions (see the module
    doc), each skipped when already in ``out/loaded``.

    Raises:
        ConfigError: no run of the calibration setting, or a calibration failed.
    """
    idle = quietest(plan, out)
    base = next(c for c in plan.cells if c.name == idle)
    runs = {IDLE: out / "live" / idle, HOG: out / "loaded" / HOG / HOG_RUN}
    if not (runs[HOG] / "summary.json").exists():
        say(f"{HOG_RUN}: the calibration setting with a CPU hog busy on one core")
        with Hog(live_timeout(plan) + 60.0):
            live_cell(replace(base, name=HOG_RUN), plan, runs[HOG])
    for name, run in runs.items():
        d = out / "loaded" / name
        if _calibrated_on(d) != run.name:  # none yet, or another repeat is the quietest now
            say(f"{name}: calibrating on {run.name} alone")
            (d / "des.json").unlink(missing_ok=True)
            calibrate_run([run], d / "cal", timeout=1200.0)
        if (d / "des.json").exists():
            continue
        say(f"{name}: predicting the held-out cells")
        cal, report = load_calibration(d / "cal")
        pred: dict[str, Any] = {}
        for cell in plan.cells:
            if cell.held_out and cell.copy == 1:
                with tempfile.TemporaryDirectory() as tmp:
                    r = des_cell(cal, report, cell, plan, Path(tmp))
                pred[cell.name] = {m: {k: float(f[k]) for k in METRICS}
                                   for m, f in r["methods"].items()}
        (d / "des.json").write_text(json.dumps(pred, indent=1))


def loaded_rows(rows: list[dict[str, Any]], out: Path, cores: int, f_trig: float
                ) -> list[dict[str, Any]]:
    """``loaded.csv``'s rows: for each calibration of ``out/loaded`` (idle first), its
    runs' largest background, whether ``predict`` refuses it, and per metric the held-out
    cells its predictions put within the headline's band (scored as ``cells.csv``'s
    ``rows`` are: the same live values, floors and repeats); none without the folder."""
    held = [r for r in rows if r["held_out"]]
    out_rows: list[dict[str, Any]] = []
    for name in (IDLE, HOG):
        d = out / "loaded" / name
        if not (d / "des.json").exists():
            continue
        pred = json.loads((d / "des.json").read_text())
        report = read_json(d / "cal" / "calibrated.json") or {}
        bgs = [float(v) for v in (report.get("background_cores_of_runs") or {}).values()]
        bg = max((b for b in bgs if math.isfinite(b)), default=math.nan)
        run = _calibrated_on(d)
        refused = bool(loaded_runs(report, cores))
        for k in METRICS:
            verdicts = []
            for r in held:
                if r["metric"] != k or r["cell"] not in pred:
                    continue
                reps = live_repeats(r)
                verdicts.append(judge(k, r["live"], pred[r["cell"]][r["method"]][k],
                                      r["noise_floor"], f_trig, reps if len(reps) > 1 else ()))
            scored = [v for v in verdicts if v.scored]
            out_rows.append({"calibration": name, "run": run, "background_cores": bg,
                             "refused": refused,
                             "metric": k, "within": sum(v.within_band for v in scored),
                             "scored": len(scored)})
    return out_rows


def loaded_target(lrows: list[dict[str, Any]], cores: int) -> str | None:
    """The target's line of ``summary.md``, ticked when the loaded calibration is refused
    or is within the band on at least as many cells as the idle one on every metric;
    None without both calibrations' rows."""
    by = {(r["calibration"], r["metric"]): r for r in lrows}
    if not all((c, k) in by for c in (IDLE, HOG) for k in METRICS):
        return None
    refused = by[(HOG, METRICS[0])]["refused"]
    as_good = all(by[(HOG, k)]["within"] >= by[(IDLE, k)]["within"] for k in METRICS)
    why = ("refused by `predict` and `capacity` (background above "
           f"{UNDER_LOAD:.0%} of the {cores} cores)" if refused else
           "not refused" + ("; as many cells within the band as the idle one" if as_good
                            else "; fewer cells within the band than the idle one"))
    return (f"- [{'x' if refused or as_good else ' '}] a calibration under load is refused, "
            f"or predicts as well as an idle one: {why}")


def loaded_md(lrows: list[dict[str, Any]], cores: int) -> list[str]:
    """The section of ``summary.md``: both calibrations' shares and the verdict
    (:func:`loaded_target`). Nothing without both calibrations' rows."""
    target = loaded_target(lrows, cores)
    if target is None:
        return []
    by = {(r["calibration"], r["metric"]): r for r in lrows}
    body = [[f"{c} (`{by[(c, METRICS[0])]['run']}`)",
             f"{by[(c, METRICS[0])]['background_cores']:.2f}",
             "yes" if by[(c, METRICS[0])]["refused"] else "no",
             *[f"{by[(c, k)]['within']} / {by[(c, k)]['scored']}" for k in METRICS]]
            for c in (IDLE, HOG)]
    return ["", "## A calibration under load", "",
            "The calibration setting run once more with a CPU hog busy on one core, "
            "calibrated on that run alone, against the setting's quietest repeat (the "
            "least background CPU) calibrated alone: held-out cells within the headline's "
            "band from each (the same live values and rule as above; a one-run calibration "
            "has no bundled run, so its bundled cells are predicted with the per-node "
            "hops).", "",
            md_table(["calibration", "background (cores)", "refused", *METRICS], body), "",
            target]
