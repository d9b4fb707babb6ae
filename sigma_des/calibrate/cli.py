"""The ``sigma-des calibrate`` subcommand: fit the DES to a live run, write a scenario.

``calibrate`` fits DES parameters from a ``sigma-des live --out`` directory (or an
MCAP recording), writes a scenario TOML that ``compare`` runs and its report (JSON),
with the in-sample check and warnings about what it could not fit.
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path
from typing import IO

from sigma_des.errors import ConfigError

__all__ = ["add_calibrate_args", "run_calibrate"]


def add_calibrate_args(p: argparse.ArgumentParser) -> None:
    """Add the arguments of ``calibrate`` to its subparser ``p``."""
    p.add_argument("source", help="a `sigma-des live --out` directory or an MCAP recording")
    p.add_argument("--out", default=None, metavar="SCENARIO.toml",
                   help="write the calibrated scenario here, the report next to it as "
                   "SCENARIO.json (default: print the scenario)")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="fit even when hosts' per-node rows are missing (with a warning)")
    p.add_argument("--hold-tol", type=float, default=None, metavar="SECONDS",
                   help="a delivery this close after the previous one on its connection "
                   "counts as held behind it when latencies are de-queued (default 1e-4; "
                   "0: keep the measured latencies)")
    p.add_argument("--no-check", action="store_true",
                   help="skip the in-sample check (the calibrated DES re-running the live run)")
    p.add_argument("--one-thread", action="store_true",
                   help="fit each process as one thread even when the live run recorded its "
                   "threads apart (default: the loop and paho's network thread apart; "
                   "docs/concepts/deployment.md, 'The network thread')")
    p.add_argument("--runq-growth", action="store_true",
                   help="run-queue waits that grow with the DES machine's load (Erlang C; "
                   "default: each process kind's measured wait per CPU second, kept; "
                   "docs/concepts/deployment.md, 'Run-queue waits')")
    p.add_argument("--no-match", action="store_true",
                   help="keep the fitted hop latencies as they are (default: rescale each "
                   "direction's until the DES re-predicts the run's mean state and trigger "
                   "latency within 3 %%; docs/concepts/live-and-calibration.md)")


def _put(body: str, fh: IO[str]) -> None:
    fh.write(body)


def run_calibrate(args: argparse.Namespace) -> int:
    """Run ``calibrate``; ConfigError propagates (exit 2). Warnings go to stderr."""
    import json

    from sigma_des.calibrate.fit import (
        calibrate,
        calibrated_toml,
        remove_files,
        report_lines,
        sample_files,
    )
    from sigma_des.calibrate.insample import in_sample

    source = Path(args.source)
    from sigma_des.calibrate.dequeue import HOLD_TOL
    from sigma_des.guard import atomic_write, input_file, output_file

    tol = HOLD_TOL if args.hold_tol is None else args.hold_tol
    if not source.is_dir():
        input_file(source, str(source), "live run directory, messages.csv.gz or MCAP recording")
    if args.out:  # a bad output location must cost nothing: checked before the fit
        output_file(args.out, "--out")
        output_file(Path(args.out).with_suffix(".json"), "--out")
    sc, report = calibrate(source, Path(args.out).parent if args.out else None,
                           strict=not args.allow_incomplete, hold_tol=tol,
                           threads=not args.one_thread, runq_growth=args.runq_growth)
    out_dir = Path(args.out).parent if args.out else (source if source.is_dir()
                                                      else source.parent)
    if not args.no_match:
        from sigma_des.calibrate.match import match_hops

        sc, matched = match_hops(sc, source, out_dir)
        report.update(matched)
    if not args.no_check:
        rows, warn = in_sample(sc, source)
        report["in_sample"] = rows
        report["warnings"] += warn
    text = calibrated_toml(sc, report)
    if args.out:
        out = Path(args.out)
        rep = out.with_suffix(".json")
        rep_text = json.dumps(report, indent=2, default=float) + "\n"
        written = sample_files(sc)  # the set is the samples, the scenario, the report
        try:
            for path, body in ((out, text), (rep, rep_text)):
                atomic_write(path, partial(_put, body))
                written.append(path)
        except ConfigError:
            remove_files(written)
            raise
        _warn(report["warnings"])  # after the writes: a failed one is then the one line
        print(f"wrote {out} and {rep}")
        for line in report_lines(report):
            if not line.startswith("warning: "):
                print(f"  {line}")
    else:
        _warn(report["warnings"])
        sys.stdout.write(text)
    return 0


def _warn(warnings: list[str]) -> None:
    for w in warnings:
        print(f"sigma-des: warning: {w}", file=sys.stderr)
