#!/usr/bin/env python
"""Benchmark the cohort engine, the per-message engine and a process-per-message SimPy model.

Every case runs in a fresh child process (peak RSS per case, single-threaded); the
cases, the metric checks (cohort vs events bit-identical, cohort vs baseline within
``BASELINE_RTOL``) and the caps at large N are described in
:mod:`sigma_des.studies.engine_bench` and ``docs/BENCHMARKS.md``. The exit status is 1
if a check fails.

Examples::

    python experiments/bench_engine.py                      # N = 200,1000,10000, 5 s each
    python experiments/bench_engine.py --quick --out q.csv  # N = 10,50, 1 s (tests)
    python experiments/bench_engine.py --nodes 200 --methods all
    python experiments/bench_engine.py --nodes 200 --set compute.step_time=0.0008

Timing figures depend on the machine; nothing here asserts on them.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any

from sigma_des.studies.engine_bench import (
    ALL_METHODS,
    BASELINE_RTOL,
    COLUMNS,
    COMPARED,
    NODES_PER_HOST,
    THREAD_VARS,
    Check,
    annotate,
    baseline_estimate_s,
    make_row,
    overrides_for,
    plan,
    run_fresh,
)
from sigma_des.studies.engine_tables import check_table, metric_table, speed_table, speedup_table

HERE = Path(__file__).resolve().parent


def _machine() -> str:
    """CPU model, logical CPUs, Python and SimPy versions and the git commit."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=HERE,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    import simpy

    return (
        f"{cpu}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, "
        f"SimPy {simpy.__version__}; commit {commit or '?'}"
    )


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (module doc); ``--quick`` is N = 10,50 for 1 s."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", default="200,1000,10000", help="comma-separated node counts")
    p.add_argument("--duration", type=float, default=5.0, help="simulated seconds per case")
    p.add_argument(
        "--methods",
        default="bides",
        help="methods timed on the full scenario: comma-separated, or 'all' "
        f"({','.join(ALL_METHODS)})",
    )
    p.add_argument(
        "--baseline",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also run the process-per-message SimPy baseline (restricted scenario)",
    )
    p.add_argument(
        "--events-cap",
        type=float,
        default=2.0,
        help="at N >= --large-n the events cases simulate min(duration, this)",
    )
    p.add_argument(
        "--baseline-cap",
        type=float,
        default=2.0,
        help="at N >= --large-n the baseline simulates min(duration, this)",
    )
    p.add_argument(
        "--baseline-max-n",
        type=int,
        default=1000,
        help="skip the baseline above this N (it would take many minutes)",
    )
    p.add_argument("--large-n", type=int, default=1000, help="see --events-cap, --baseline-cap")
    p.add_argument("--quick", action="store_true", help="tiny run: N = 10,50, 1 s (for tests)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override applied to every case (repeatable)",
    )
    p.add_argument("--cpu", type=int, default=None, help="pin every case to this CPU")
    p.add_argument(
        "--start-method",
        choices=("forkserver", "spawn"),
        default="forkserver",
        help="how each case's fresh process is started (default: forkserver)",
    )
    p.add_argument("--out", type=Path, default=None, help="write the rows to this CSV file")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration = "10,50", 1.0
    try:
        a.node_list = [int(x) for x in str(a.nodes).split(",") if x.strip()]
    except ValueError:
        p.error(f"--nodes: not a comma-separated list of integers: {a.nodes!r}")
    if a.methods.strip() == "all":
        a.method_list = list(ALL_METHODS)
    else:
        a.method_list = [m.strip() for m in a.methods.split(",") if m.strip()]
    bad = [m for m in a.method_list if m not in ALL_METHODS]
    if bad:
        p.error(f"--methods: unknown {', '.join(bad)}; allowed: {','.join(ALL_METHODS)} or all")
    for opt in ("duration", "events_cap", "baseline_cap"):
        if not getattr(a, opt) > 0:
            p.error(f"--{opt.replace('_', '-')} must be > 0")
    return a


def node_notes(a: argparse.Namespace, n: int, rows: list[dict[str, Any]]) -> list[str]:
    """The notes on the caps and the skipped baseline at ``n`` nodes (printed at the end)."""
    notes: list[str] = []
    big = n >= a.large_n
    if big and a.events_cap < a.duration:
        notes.append(
            f"N={n}: the events engine (and its cohort twin) simulates {a.events_cap:g} s "
            f"instead of {a.duration:g} s (--events-cap)"
        )
    with_baseline = a.baseline and n <= a.baseline_max_n
    if a.baseline and not with_baseline:
        dur_b = min(a.duration, a.baseline_cap) if big else a.duration
        est = baseline_estimate_s(rows, n, dur_b)
        took = f"> {math.floor(est / 60)} minutes" if est >= 120 else f"~{est:.0f} s"
        msg = (
            f"N={n}: baseline skipped (--baseline-max-n {a.baseline_max_n}): the baseline "
            f"would take {took} ({dur_b:g} s simulated, linear in N)"
        )
        notes.append(msg)
        print("  " + msg, flush=True)
    elif with_baseline and big and a.baseline_cap < a.duration:
        notes.append(
            f"N={n}: the baseline (and its cohort twin) simulates {a.baseline_cap:g} s "
            f"instead of {a.duration:g} s (--baseline-cap)"
        )
    return notes


def run_node(
    a: argparse.Namespace, n: int, rows: list[dict[str, Any]], notes: list[str]
) -> None:
    """Run every case of ``n`` nodes (each in a fresh process), appending rows and notes."""
    cap_b = a.baseline_cap if a.baseline and n <= a.baseline_max_n else None
    for case in plan(n, a.method_list, a.duration, a.events_cap, cap_b, a.large_n):
        ov = overrides_for(n, case.sim_s, case.scenario == "restricted", a.set, case.impl)
        res = run_fresh(case.impl, case.method, ov, a.cpu, a.start_method)
        rows.append(make_row(case, n, res))
        print(
            f"  N={n:<6} {case.impl + ('~' if case.role == 'twin' else ''):<9} "
            f"{case.method:<8} {case.scenario:<10} {case.sim_s:5g} s sim "
            f"{res['wall_s']:9.2f} s wall  ({res['engine_used']})",
            flush=True,
        )
        if res["fallback"]:
            note = f"{case.method} on the {case.scenario} scenario: cohort fell back to the "
            note += f"per-message engine: {res['fallback']}"
            if note not in notes:
                notes.append(note)


def print_tables(rows: list[dict[str, Any]], checks: list[Check], notes: list[str]) -> None:
    """The speed, speed-up, metric-check and cohort-vs-baseline tables, then the notes."""
    print()
    print(
        "Speed (s/s = wall seconds per simulated second, xRT = times real time, "
        "ev/s = events per wall second;"
    )
    print(
        "full = commands on; restricted = commands off, the baseline's scenario class; "
        "cohort~ = cohort twin at a capped duration)"
    )
    print(speed_table(rows))
    print()
    print("Speed-up (ratio of wall seconds per simulated second; - = not measured)")
    print(speedup_table(rows))
    print()
    print(
        "Metric checks (same simulated duration; cohort vs events: every metric, must be "
        f"identical; cohort vs baseline: {len(COMPARED)} metrics, rel. diff <= "
        f"{BASELINE_RTOL:.0e})"
    )
    print(check_table(checks))
    if any(r["impl"] == "baseline" for r in rows):
        print()
        print(
            "Metrics, cohort vs baseline (method none, restricted scenario, same seed;"
            " ms, Hz, Mbps)"
        )
        print(metric_table(rows))
    for note in notes:
        print("note:", note)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit status 1 if a metric check fails."""
    a = parse_args(argv)
    for var in THREAD_VARS:  # one core per case: no BLAS/numba worker threads
        os.environ.setdefault(var, "1")
    print(f"sigma_des engine benchmark: cohort vs events vs baseline  ({_machine()})")
    print(
        f"scenario: defaults + {NODES_PER_HOST} nodes/host, duration {a.duration:g} s "
        f"(warm-up {min(1.0, 0.2 * a.duration):g} s); overrides: {a.set or 'none'}"
    )
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    if a.baseline:
        from sigma_des.config import load
        from sigma_des.reference.process_model import Unsupported, check_supported

        try:
            check_supported(load(overrides=overrides_for(10, a.duration, True, a.set)))
        except Unsupported as err:
            notes.append(f"no baseline: {err}")
            a.baseline = False
    for n in a.node_list:
        notes += node_notes(a, n, rows)
        run_node(a, n, rows, notes)
    checks = annotate(rows)
    print_tables(rows, checks, notes)
    if a.out is not None:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        with a.out.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow(r)
        print(f"wrote {a.out}")
    failed = [c for c in checks if not c.ok]
    if failed:
        print(f"FAILED: {len(failed)} metric check(s) (see 'Metric checks' above)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
