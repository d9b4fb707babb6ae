"""Run the validation plan: live cells, the calibration, the DES predictions — resumably.

Every finished piece is a file in ``--out`` and is kept when the suite is run again
with the same ``--out`` (an interrupted run picks up where it stopped):

* ``live/<cell>/`` — the live run's ``sigma-des live --out`` files, and
  ``cells/<cell>.live.json`` — its figures, load and background CPU; after the plan's
  cells, live's knee runs (``knee-n<N>-<mode>``, :attr:`Plan.knee_live`) while some
  method still holds at the largest size live ran in that mode;
* ``cal/`` — ``calibrated.toml``, ``calibrated.json`` (the report, in-sample errors
  included), the latency sample files, ``calibrate.log`` and ``source.json`` (the runs
  it was fitted to: every repeat of the calibration setting, the most typical first,
  :func:`~sigma_lab.studies.validation.scoring.central`, and the further bundled runs;
  and a fingerprint of each run it read: a calibration run made again makes the
  calibration stale);
* ``cells/des-<key>.json`` — one DES prediction (every method), stamped with the
  calibration it used (a new calibration makes it stale: it is run again).

All live cells run first (the DES runs and the calibration would load the machine
under them), then the calibration on the repeats, then its predictions.
Progress goes to stderr, one line per piece.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError
from sigma_lab.studies.validation.grid import MODES, Cell, Plan
from sigma_lab.studies.validation.runs import (
    LIVE_BASE,
    calibrate_run,
    des_cell,
    live_cell,
    load_calibration,
    read_json,
    under_load,
    warm_up,
    write_json,
)
from sigma_lab.studies.validation.scoring import central

__all__ = ["Outcome", "calibration_cell", "calibration_kept", "des_key", "holding", "run_again",
           "run_suite", "runs_stamp", "set_aside"]

Say = Callable[[str], None]
#: What the report needs: live figures per cell, DES figures per key, the calibration.
Outcome = tuple[dict[str, dict[str, Any]], dict[str, dict[str, Any]], dict[str, Any]]


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def des_key(cell: Cell) -> str:
    """The DES prediction a cell needs (repeats share one; knee and grid cells too)."""
    return f"n{cell.nodes}-{cell.mode}" + (f"-{cell.impairment}" if cell.impairment else "")


def _clock(s: float) -> str:
    return f"{int(s // 60)}:{int(s % 60):02d}"


def run_again(res: dict[str, Any] | None, plan: Plan, cores: int) -> bool:
    """Whether a live cell runs (again): it has no finished run, or its run was under
    load (:func:`~sigma_lab.studies.validation.runs.under_load`) and it has been tried
    at most :attr:`Plan.retry_loaded` times (``tries`` in its figures; 1 if absent)."""
    if res is None or not res.get("methods"):
        return True
    return under_load(res, cores) and int(res.get("tries", 1)) <= plan.retry_loaded


def set_aside(out: Path, cell: str, tries: int) -> Path:
    """Move a loaded live run of ``cell`` (``live/<cell>/``) to ``loaded/<cell>-<tries>/``,
    outside ``live/`` (whose copies of a cell the reports read); the destination."""
    dest = out / "loaded" / f"{cell}-{tries}"
    src = out / "live" / cell
    if src.exists():
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(dest, ignore_errors=True)
        src.rename(dest)
    return dest


def _live_all(plan: Plan, out: Path, say: Say, t0: float) -> dict[str, dict[str, Any]]:
    live: dict[str, dict[str, Any]] = {}
    per = plan.estimate() / max(1, len(plan.cells))
    for i, cell in enumerate(plan.cells, 1):
        live[cell.name], ran = _live_kept_or_run(plan, cell, out, say, f"[{i}/{len(plan.cells)}]")
        if ran:
            say(f"    elapsed {_clock(time.perf_counter() - t0)}, live cells left ~"
                f"{_clock(per * (len(plan.cells) - i))}")
    _knee_live(plan, live, out, say)
    _knee_tiebreak(plan, live, out, say)
    return live


def _live_kept_or_run(plan: Plan, cell: Cell, out: Path, say: Say, tag: str
                      ) -> tuple[dict[str, Any], bool]:
    """``cell``'s live figures, and whether it ran now: kept from an earlier run, else
    run (again while it ran under load and tries are left; a loaded run is set aside)."""
    cores = os.cpu_count() or 1
    path = out / "cells" / f"{cell.name}.live.json"
    res = read_json(path)
    res = res if isinstance(res, dict) and res.get("methods") else None
    if not run_again(res, plan, cores):
        assert res is not None
        say(f"{tag} live {cell.name}: kept from an earlier run")
        return res, False
    while run_again(res, plan, cores):
        tries = 1
        if res is not None:
            tries = int(res.get("tries", 1)) + 1
            aside = set_aside(out, cell.name, tries - 1)
            say(f"{tag} live {cell.name}: ran under load (background "
                f"{res['background_cores']:.2f} cores): again, try {tries} of "
                f"{plan.retry_loaded + 1} (the loaded run in {aside.relative_to(out)})")
        res = _live_one(plan, cell, out, say, tag)
        res["tries"] = tries
        write_json(path, res)
    assert res is not None
    return res, True


def holding(plan: Plan, live: dict[str, dict[str, Any]], mode: str, f_trig: float
            ) -> list[str]:
    """The methods whose live figures hold (``sigma-des capacity``'s predicate) at the
    largest size live ran in ``mode`` without an impairment (the mean of that size's
    runs; a method without figures there does not hold)."""
    from sigma_des.calibrate.capacity import holds
    from sigma_lab.studies.validation.scoring import KNEE_MISSED

    ran = [c for c in (*plan.cells, *plan.knee_live_cells(mode))
           if c.mode == mode and not c.impairment and c.name in live]
    if not ran:
        return []
    top = max(c.nodes for c in ran)
    runs = [live[c.name]["methods"] for c in ran if c.nodes == top]

    def mean(m: str, k: str) -> float:
        xs = [float(r[m].get(k, math.nan)) for r in runs if m in r]
        ok = [x for x in xs if math.isfinite(x)]
        return sum(ok) / len(ok) if ok else math.nan

    return [m for m in plan.methods if holds(mean(m, "trigger_rate_hz"),
                                             mean(m, "missed_frac"), math.nan, f_trig,
                                             KNEE_MISSED, None)]


def _live_f_trig() -> float:
    """The trigger rate the live runs ran (the knee's held-rate predicate needs it)."""
    from sigma_des.config import load

    return load(None, list(LIVE_BASE)).f_trig


def _knee_live(plan: Plan, live: dict[str, dict[str, Any]], out: Path, say: Say) -> None:
    """Live's knee runs: per mode, the next :attr:`Plan.knee_live` size while a method
    still holds at the largest size live ran (added to ``live``)."""
    f_trig = _live_f_trig()
    for mode in MODES:
        for cell in plan.knee_live_cells(mode):
            still = holding(plan, live, mode, f_trig)
            if not still:
                break
            say(f"[knee] {', '.join(still)} still hold(s) {mode}: live at N = {cell.nodes}")
            live[cell.name] = _live_kept_or_run(plan, cell, out, say, "[knee]")[0]


def _knee_tiebreak(plan: Plan, live: dict[str, dict[str, Any]], out: Path, say: Say) -> None:
    """Per mode, :attr:`Plan.knee_tiebreak` more live runs of each held-out size of live's
    knee grid whose runs disagree about holding (added to ``live``): the mean of an odd
    number of runs decides live's knee there."""
    from sigma_lab.studies.validation.knees import disputed_points

    if not plan.knee_tiebreak:
        return
    f_trig = _live_f_trig()
    for mode in MODES:
        for cell, methods in disputed_points(plan, live, mode, f_trig):
            for extra in plan.tiebreak_cells(cell):
                say(f"[knee] {cell.name}: live's runs disagree about holding "
                    f"({', '.join(methods)}): {extra.name}")
                live[extra.name] = _live_kept_or_run(plan, extra, out, say, "[knee]")[0]


def _live_one(plan: Plan, cell: Cell, out: Path, say: Say, tag: str) -> dict[str, Any]:
    """Run one live cell, saying what and how it went."""
    say(f"{tag} live {cell.name}: N = {cell.nodes} on {cell.hosts} hosts, {cell.mode} "
        f"messages{', ' + cell.impairment if cell.impairment else ''}, "
        f"{len(plan.methods)} methods x {plan.duration:g} s ...")
    res = live_cell(cell, plan, out / "live" / cell.name)
    note = " TIMED OUT" if res["timed_out"] else ""
    note += f" exit {res['exit']}" if res["exit"] else ""
    say(f"    done in {res['wall_s']:.0f} s{note}; load {res['load_before']:.1f} -> "
        f"{res['load_after']:.1f}, background {res['background_cores']:.2f} cores")
    return res


def calibration_cell(plan: Plan, live: dict[str, dict[str, Any]]) -> str:
    """The calibration's primary run (its step time and scenario keys): the most
    typical repeat of those that ran
    (:func:`~sigma_lab.studies.validation.scoring.central`)."""
    reps = {c.name: live[c.name]["methods"] for c in plan.cells
            if c.repeat and c.name in live}
    if not reps:
        raise ConfigError("calibration", "no run of the calibration setting finished")
    return central(reps)


def _calibration(plan: Plan, live: dict[str, dict[str, Any]], out: Path, say: Say,
                 args: Sequence[str]) -> None:
    name = calibration_cell(plan, live)
    # every repeat, the most typical first (the campaign's primary run): their per-message
    # CPU averaged and their hop samples pooled; then the further (bundled) runs
    cells = [name] + [c.name for c in plan.cells if c.repeat and c.name != name
                      and c.name in live] + [c.name for c in plan.cells
                                             if c.cal_extra and c.name in live]
    source = {"cell": name, "cells": cells, "args": list(args), "runs": runs_stamp(out, cells)}
    if calibration_kept(out, source):
        say(f"calibration: kept from an earlier run (on {', '.join(cells)})")
        return
    say(f"calibrating on {', '.join(cells)} ({name} first: the most typical of the "
        f"calibration setting's {sum(1 for c in plan.cells if c.repeat and c.name in live)} "
        "runs; `sigma-des calibrate`, with its in-sample check on each) ...")
    t = time.perf_counter()
    calibrate_run([out / "live" / c for c in cells], out / "cal", extra=args)
    write_json(out / "cal" / "source.json", source)
    say(f"    calibrated in {time.perf_counter() - t:.0f} s")


def runs_stamp(out: Path, cells: Sequence[str]) -> dict[str, str]:
    """A fingerprint of each live run a calibration reads (its ``summary.json``): a run
    made again since (e.g. one deleted because it ran under load) changes it."""
    stamps = {}
    for c in cells:
        path = out / "live" / c / "summary.json"
        stamps[c] = hashlib.sha256(path.read_bytes()).hexdigest()[:16] if path.exists() else ""
    return stamps


def calibration_kept(out: Path, source: dict[str, Any]) -> bool:
    """Whether ``out/cal`` holds a calibration made from exactly ``source`` (the cells,
    ``calibrate`` options and run fingerprints :func:`_calibration` would use now); a
    calibration of an older copy of a run, or one recorded without fingerprints, is
    not kept."""
    kept = read_json(out / "cal" / "source.json")
    if read_json(out / "cal" / "calibrated.json") is None or not isinstance(kept, dict):
        return False
    return all(kept.get(k) == source[k] for k in ("cells", "args", "runs"))


def _cal_stamp(out: Path) -> str:
    h = hashlib.sha256()
    for name in ("calibrated.toml", "calibrated.json"):
        h.update((out / "cal" / name).read_bytes())
    return h.hexdigest()[:16]


def _des_all(plan: Plan, out: Path, say: Say, t0: float) -> dict[str, dict[str, Any]]:
    cal, report = load_calibration(out / "cal")
    stamp = _cal_stamp(out)
    wanted: dict[str, Cell] = {}
    for c in (*plan.cells, *plan.knee_cells()):
        wanted.setdefault(des_key(c), c)
    des: dict[str, dict[str, Any]] = {}
    for i, (key, cell) in enumerate(wanted.items(), 1):
        path = out / "cells" / f"des-{key}.json"
        kept = read_json(path)
        if kept is not None and kept.get("calibration") == stamp:
            des[key] = kept
            continue
        res = des_cell(cal, report, cell, plan, out / "cells" / "samples")
        res["calibration"] = stamp
        write_json(path, res)
        des[key] = res
        fb = {v["fallback"] for v in res["methods"].values() if v["fallback"]}
        say(f"[des {i}/{len(wanted)}] {key}: {res['wall_s']:.1f} s"
            + (f" (engine fallback: {'; '.join(sorted(fb))[:120]})" if fb else "")
            + f"; elapsed {_clock(time.perf_counter() - t0)}")
    return des


def run_suite(plan: Plan, out: Path, say: Say = _say,
              calibrate_args: Sequence[str] = ()) -> Outcome:
    """Run (or pick up) every piece of ``plan`` in ``out``; ``calibrate_args``: more
    ``sigma-des calibrate`` options (a kept calibration made with other ones is redone,
    and so are the DES cells that used it).

    Returns:
        Live figures per cell name, DES figures per :func:`des_key`, and the
        calibration report.
    """
    for d in ("cells", "live", "cal"):
        (out / d).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    say(f"validation: {len(plan.cells)} live cells x {len(plan.methods)} methods, "
        f"{plan.duration:g} s runs; {len(plan.knee_cells())} knee-grid DES cells; expected "
        f"wall time ~{_clock(plan.estimate())} on an idle 2-core machine")
    say("compiling the numba kernels first (`sigma-des warmup`) ...")
    code = warm_up(out / "warmup.log")
    if code:
        say(f"    warmup exited {code} (see {out / 'warmup.log'}): the first live run may "
            "hold compile stalls")
    live = _live_all(plan, out, say, t0)
    _calibration(plan, live, out, say, calibrate_args)
    des = _des_all(plan, out, say, t0)
    report = read_json(out / "cal" / "calibrated.json") or {}
    src = read_json(out / "cal" / "source.json") or {}
    report["calibration_cell"] = src.get("cell")
    report["calibration_cells"] = src.get("cells", [src.get("cell")])
    say(f"validation: all runs done in {_clock(time.perf_counter() - t0)}")
    return live, des, report
