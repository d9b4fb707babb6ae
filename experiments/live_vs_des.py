#!/usr/bin/env python
"""Validation suite: calibrate the DES on ONE live run, then predict held-out live runs.

1. Live calibration run ``cal-r1``: N = 20 on 2 hosts, per-node messages, every
   method; ``sigma-des calibrate`` fits the DES to it (and checks it in-sample).
2. Held-out live cells, each predicted by the calibrated DES with only the cell's
   keys changed: N in {10, 30, 60, 100} on ``max(2, ceil(N / 25))`` hosts (2, 2, 3,
   4), per-node and bundled messages (live ``--bundle``; DES
   ``deployment.clients = "host"``, ``deployment.bundle = true``), and at N = 30
   5 % loss and +5 ms on every host link, both message modes.
3. The calibration setting twice more (``cal-r2`` mid-grid, ``cal-r3`` last): the
   live noise floor, reported beside every error.
4. The DES alone on a finer N grid (10 … 150) for its knee: the smallest N missing
   more than 5 % of frames, against live's.
5. (``--loaded-check``) The calibration setting once more with a CPU hog busy on one
   core: a calibration on that run alone against one on the setting's quietest repeat
   alone, both scored on the held-out cells (refused by ``predict``, or as good as the
   idle one).

Every live run is bounded (a time limit, then SIGTERM, then SIGKILL), on loopback,
with the project's own Mosquitto; its load average and background CPU are kept, and
a cell that ran under load runs again (``--retry-loaded``). Rerunning with the same
``--out`` keeps every finished cell (a results file per cell) and recalibrates when a
calibration run was made again. The rules and outputs:
``sigma_lab.studies.validation`` and lab/record/LIVE.md (*Validation*).

    python experiments/live_vs_des.py --out out/validation        # ~15 min on 2 idle cores
    python experiments/live_vs_des.py --grid 'n30-*,lat5-node' --out out/v   # a subset
    python experiments/live_vs_des.py --quick --out /tmp/v        # smoke run (~1-2 min)
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Any

from sigma_lab.studies.validation import full_plan, quick_plan, run_suite, write_outputs
from sigma_lab.studies.validation.loaded import run_loaded
from sigma_lab.studies.validation.runs import load_calibration

from sigma_des.config import METHODS
from sigma_des.errors import ConfigError


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the suite and write its outputs into ``--out``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="out/validation", help="output folder (resumable)")
    p.add_argument("--quick", action="store_true",
                   help="smoke run: N = 4 and 6, 1.5 s runs, none and bides")
    p.add_argument("--grid", default=None, metavar="GLOBS",
                   help="only these cells (comma-separated globs, e.g. 'n30-*,loss5-node'); "
                        "cal-r1 always runs")
    p.add_argument("--methods", default=None, help="comma-separated (default: all four)")
    p.add_argument("--duration", type=float, default=None,
                   help="seconds per live and DES run (default 4; --quick 1.5)")
    p.add_argument("--cell-repeats", type=int, default=None, metavar="K",
                   help="live runs of each held-out cell (default 2; --quick 1): the live "
                        "range a noisy cell's prediction is scored against")
    p.add_argument("--calibrate-args", default="", metavar="ARGS",
                   help="more `sigma-des calibrate` options, one string given with '=' "
                        "(e.g. --calibrate-args=--one-thread); a kept calibration made "
                        "with others is redone")
    p.add_argument("--calibrate-bundled", action="store_true",
                   help="also run the calibration setting with bundled messages twice "
                        "(cal-bundle, cal-bundle-r2) and calibrate on them with the most "
                        "typical repeat (`sigma-des calibrate RUN RUN RUN`: the bundled hop "
                        "factor matched on the bundled runs' mean)")
    p.add_argument("--retry-loaded", type=int, default=None, metavar="K",
                   help="run a live cell again when it ran under load (background CPU > "
                        "25%% of the cores), at most K times (default 1; --quick 0); the "
                        "loaded runs are kept in OUT/loaded/")
    p.add_argument("--knee-tiebreak", type=int, default=None, metavar="K",
                   help="more live runs (0..3) of a held-out size whose runs disagree about "
                        "holding the rate and the missed-frame budget: live's knee decided "
                        "by the mean of an odd number of runs (default 1; --quick 0)")
    p.add_argument("--loaded-check", action="store_true",
                   help="also run the calibration setting once with a CPU hog busy on one "
                        "core, calibrate on it alone and on the quietest repeat alone, and "
                        "score both on the held-out cells (loaded.csv; ~2 min more)")
    p.add_argument("--estimate", action="store_true", help="print the expected wall time, exit")
    a = p.parse_args(argv)
    methods = tuple(a.methods.split(",")) if a.methods else (
        ("none", "bides") if a.quick else tuple(METHODS))
    try:
        unknown = [m for m in methods if m not in METHODS]
        if unknown:
            raise ConfigError("--methods", f"unknown {unknown}; allowed: {', '.join(METHODS)}")
        make = quick_plan if a.quick else full_plan
        kw: dict[str, Any] = {k: v for k, v in (("duration", a.duration),
                                                   ("cell_repeats", a.cell_repeats),
                                                   ("retry_loaded", a.retry_loaded),
                                                   ("knee_tiebreak", a.knee_tiebreak))
                                 if v is not None}
        if a.calibrate_bundled:
            kw["cal_bundle"] = True
        plan = make(methods, **kw).select(a.grid)
    except ConfigError as e:
        print(f"live_vs_des: {e}", file=sys.stderr)
        return 2
    est = plan.estimate()
    print(f"expected wall time: ~{est / 60:.1f} min ({len(plan.cells)} live cells, "
          f"{plan.duration:g} s runs)", file=sys.stderr)
    if a.estimate:
        return 0
    out = Path(a.out).resolve()
    try:
        outcome = run_suite(plan, out, calibrate_args=shlex.split(a.calibrate_args))
        cal, _ = load_calibration(out / "cal")
        if a.loaded_check:
            run_loaded(plan, out)
    except ConfigError as e:
        print(f"live_vs_des: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"live_vs_des: interrupted; the same command resumes from {out}", file=sys.stderr)
        return 130
    command = "python experiments/live_vs_des.py " + shlex.join(argv or sys.argv[1:])
    write_outputs(plan, outcome, out, cal.f_trig, command)
    print((out / "summary.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
