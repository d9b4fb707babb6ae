#!/usr/bin/env python
"""Benchmark the cohort engine, the per-message engine and a process-per-message SimPy model.

Every case runs in a fresh child process (peak RSS per case, single-threaded); the
cases, the metric checks (cohort vs events bit-identical, cohort vs baseline within
``BASELINE_RTOL``) and the caps at large N are described in
:mod:`sigma_lab.studies.engine_bench` and ``lab/record/BENCHMARKS.md``. The exit status is 1
if a check fails.

Examples::

    python experiments/bench_engine.py                      # N = 200,1000,10000, 5 s each
    python experiments/bench_engine.py --quick --out q.csv  # N = 10,50, 1 s (tests)
    python experiments/bench_engine.py --nodes 200 --methods all
    python experiments/bench_engine.py --nodes 200 --set compute.step_time=0.0008

Timing figures depend on the machine; nothing here asserts on them.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from sigma_lab.studies.engine_bench import THREAD_VARS
from sigma_lab.studies.engine_driver import (
    bench_options,
    bench_parser,
    exit_status,
    header_lines,
    machine_info,
    run_bench,
    write_csv,
)
from sigma_lab.studies.engine_tables import report_text

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit status 1 if a metric check fails."""
    opts = bench_options(bench_parser(__doc__.split("\n\n")[0]), argv)
    for var in THREAD_VARS:  # one core per case: no BLAS/numba worker threads
        os.environ.setdefault(var, "1")
    for line in header_lines(opts, machine_info(HERE)):
        print(line)
    rows, checks, notes = run_bench(opts)
    print(report_text(rows, checks, notes))
    if opts.out is not None:
        write_csv(rows, opts.out)
        print(f"wrote {opts.out}")
    status, last = exit_status(checks)
    if last:
        print(last)
    return status


if __name__ == "__main__":
    sys.exit(main())
