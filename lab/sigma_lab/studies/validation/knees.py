"""The knee: live's grid and its runs, each side's capacity and knee, and the verdict.

Live's knee grid in a message mode is the unimpaired held-out cells and calibration
runs (one cell per size) and then live's knee runs (:func:`knee_grid`); a size's value
is the mean of its runs (:func:`point_runs`). The DES's knee is searched on its finer
grid (``cells/des-n<N>-<mode>.json``) and on live's, with ``sigma-des capacity``'s
predicate (:func:`~sigma_lab.studies.validation.scoring.knee_of`); :func:`knee_rows`
gives ``knee.csv``'s rows, :func:`knee_points` the plot's points. The verdict compares
the DES's knee with live's (the mean of each size's runs); beside it, each live repeat's
own knee (:func:`run_knees`) and whether the DES's is within the tolerance of one of
them: a size whose runs disagree about holding makes live's knee itself uncertain.
"""

from __future__ import annotations

import math
from typing import Any

from sigma_lab.studies.validation.grid import Cell, Plan
from sigma_lab.studies.validation.scoring import KNEE_MISSED, knee_of, knee_verdict
from sigma_lab.studies.validation.suite import Outcome

__all__ = ["copies", "copy_names", "disputed_points", "knee_grid", "knee_points", "knee_rows",
           "live_of", "point_names", "point_runs", "run_knees"]


def copy_names(plan: Plan, live: dict[str, dict[str, Any]], base: str) -> list[str]:
    """The names of held-out cell ``base``'s finished live runs (its copies, in running
    order; a live knee run, outside the plan's cells, its one run)."""
    names = [c.name for c in plan.cells if c.base == base and not c.repeat and c.name in live]
    cell = next((c for c in plan.cells if c.name == base), None)
    if cell is not None:  # a knee tie-break's further copies
        names += [c.name for c in plan.tiebreak_cells(cell) if c.name in live]
    return names or ([base] if base in live else [])


def copies(plan: Plan, live: dict[str, dict[str, Any]], base: str) -> list[dict[str, Any]]:
    """The finished live runs of held-out cell ``base`` (:func:`copy_names`)."""
    return [live[n] for n in copy_names(plan, live, base)]


def _value(run: dict[str, Any], method: str, metric: str) -> float:
    return float(run["methods"].get(method, {}).get(metric, math.nan))


def live_of(runs: list[dict[str, Any]], method: str, metric: str) -> tuple[float, list[float]]:
    """The live value of a cell (the mean of its runs' finite values) and the values."""
    xs = [_value(r, method, metric) for r in runs]
    ok = [x for x in xs if math.isfinite(x)]
    return (sum(ok) / len(ok) if ok else math.nan), xs


def knee_grid(plan: Plan, live: dict[str, dict[str, Any]], mode: str) -> list[Cell]:
    """Live's knee grid in ``mode``: the unimpaired held-out cells and the calibration
    runs that ran (one per size), then live's knee runs that ran."""
    pts = {c.nodes: c for c in reversed(plan.cells) if c.mode == mode and not c.impairment
           and c.repeat <= 1 and c.copy == 1 and c.name in live}  # the first of a size
    return [pts[n] for n in sorted(pts)] + [c for c in plan.knee_live_cells(mode)
                                           if c.name in live]


def point_names(plan: Plan, live: dict[str, dict[str, Any]], c: Cell) -> list[str]:
    """The names of knee point ``c``'s live runs: a held-out cell's copies, a campaign's
    further calibration runs of its size and mode (repeats), a repeat's own run."""
    if c.cal_extra:
        return [x.name for x in plan.cells if x.cal_extra and x.mode == c.mode
                and x.nodes == c.nodes and x.name in live]
    return [c.name] if c.repeat else copy_names(plan, live, c.name)


def point_runs(plan: Plan, live: dict[str, dict[str, Any]], c: Cell) -> list[dict[str, Any]]:
    """The live runs of knee point ``c`` (:func:`point_names`)."""
    return [live[n] for n in point_names(plan, live, c)]


def knee_rows(plan: Plan, outcome: Outcome, f_trig: float = 100.0) -> list[dict[str, Any]]:
    """Per mode and method: live's capacity and knee on its grid, the DES's on its finer
    grid (and on live's), by ``sigma-des capacity``'s search (:func:`knee_of`), and the
    verdict."""
    live, des, _ = outcome
    rows = []
    for mode in ("node", "bundle"):
        pts = knee_grid(plan, live, mode)
        if not pts:
            continue
        ns = [c.nodes for c in pts]
        fine = sorted({c.nodes for c in plan.knee_cells() if c.mode == mode} | set(ns))
        for m in plan.methods:
            lf = [{k: live_of(point_runs(plan, live, c), m, k)[0]
                   for k in ("trigger_rate_hz", "missed_frac")} for c in pts]
            lcap, lk = knee_of(ns, lf, f_trig)
            dcap, dk = knee_of(fine, [_des_fig(des, n, mode, m) for n in fine], f_trig)
            _, dg = knee_of(sorted(ns), [_des_fig(des, n, mode, m) for n in sorted(ns)],
                            f_trig)
            each = run_knees(ns, [point_runs(plan, live, c) for c in pts], m, f_trig)
            rows.append({"mode": mode, "method": m, "live_grid": " ".join(map(str, sorted(ns))),
                         "live_capacity": lcap, "live_knee": lk, "des_capacity": dcap,
                         "des_knee": dk, "des_knee_on_live_grid": dg,
                         "verdict": knee_verdict(lk, dk, max(ns)),
                         "live_run_knees": " ".join("-" if k is None else str(k) for k in each),
                         "within_a_live_run": any(knee_verdict(k, dk, max(ns)) == "met"
                                                  for k in each)})
    return rows


def disputed_points(plan: Plan, live: dict[str, dict[str, Any]], mode: str, f_trig: float
                    ) -> list[tuple[Cell, list[str]]]:
    """The held-out sizes of live's knee grid in ``mode`` whose runs (two or more)
    disagree about holding, each with the methods they disagree on."""
    from sigma_des.calibrate.capacity import holds

    out = []
    for c in knee_grid(plan, live, mode):
        runs = point_runs(plan, live, c)
        if not c.held_out or len(runs) < 2:
            continue
        split = [m for m in plan.methods
                 if len({holds(_value(r, m, "trigger_rate_hz"), _value(r, m, "missed_frac"),
                               math.nan, f_trig, KNEE_MISSED, None) for r in runs}) > 1]
        if split:
            out.append((c, split))
    return out


def run_knees(nodes: list[int], runs: list[list[dict[str, Any]]], method: str,
              f_trig: float) -> list[int | None]:
    """Live's knee on its grid by each repeat: repeat ``j`` takes every size's ``j``-th
    run (a size run fewer times, its last one). Where a size's runs fall on both sides of
    the predicate, live's knee is not one size: the repeats give each of them."""
    out = []
    for j in range(max((len(r) for r in runs), default=0)):
        figs = [{k: _value(r[min(j, len(r) - 1)], method, k)
                 for k in ("trigger_rate_hz", "missed_frac")} for r in runs]
        out.append(knee_of(nodes, figs, f_trig)[1])
    return out


def knee_points(plan: Plan, outcome: Outcome) -> dict[str, dict[str, dict[str, list[Any]]]]:
    """Per mode and method, ``live`` and ``des`` ``(N, missed_frac)`` pairs (for
    :func:`~sigma_lab.studies.validation.kneeplot.knee_plot`)."""
    live, des, _ = outcome
    out: dict[str, dict[str, dict[str, list[Any]]]] = {}
    for mode in ("node", "bundle"):
        pts = knee_grid(plan, live, mode)
        if not pts:
            continue
        fine = sorted({c.nodes for c in plan.knee_cells() if c.mode == mode}
                      | {c.nodes for c in pts})
        out[mode] = {m: {
            "live": [(c.nodes, live_of(point_runs(plan, live, c), m, "missed_frac")[0])
                     for c in pts],
            "des": [(n, _des_fig(des, n, mode, m)["missed_frac"]) for n in fine]}
            for m in plan.methods}
    return out


def _des_fig(des: dict[str, dict[str, Any]], n: int, mode: str, method: str
             ) -> dict[str, float]:
    d = des.get(f"n{n}-{mode}")
    if not d:
        return {"trigger_rate_hz": math.nan, "missed_frac": math.nan}
    return {k: float(d["methods"][method][k]) for k in ("trigger_rate_hz", "missed_frac")}
