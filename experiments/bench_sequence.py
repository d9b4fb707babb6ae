#!/usr/bin/env python
"""Many short runs in one process, as a sweep or ``compare`` runs them: the cost per run.

Runs ``sigma_des.api.run_method`` (set-up, the simulated seconds, the collector's
metrics, fidelity against the cached ideal run) ``--runs`` times in this process, one
method after another in turn (``--methods``), after an untimed two-node warm-up of
each method and the ideal run flown once, and prints per run its CPU seconds (user and
system), minor page faults (memory touched for the first time) and the process's peak
RSS so far, then the median CPU seconds per simulated second. Unlike
``bench_engine.py`` (every case in a fresh process), it shows what a run pays because
runs came before it in the process (lab/record/BENCHMARKS.md, "Issue 27, fixed per-run
costs"). Nothing here asserts on a time.

Usage::

    python experiments/bench_sequence.py --nodes 1000 --duration 1 --runs 6
    python experiments/bench_sequence.py --nodes 1000 --duration 1 --methods none,hlc,bides
    python experiments/bench_sequence.py --quick     # 10 nodes, 0.3 s, 3 runs (tests)
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import time


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=1.0)
    p.add_argument("--methods", default="bides", help="comma-separated, run in turn")
    p.add_argument("--runs", type=int, default=6)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--quick", action="store_true", help="10 nodes, 0.3 s, 3 runs (tests)")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration, a.runs = 10, 0.3, 3
    if a.runs < 1:
        print(f"bench_sequence: error: --runs: must be >= 1, got {a.runs}", file=sys.stderr)
        return 2
    from sigma_des.api import ideal_run, run_method
    from sigma_des.config import load
    from sigma_des.errors import ConfigError

    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    ov = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
          f"warmup={min(0.5, a.duration / 4)}", *a.set]
    try:
        sc = load(overrides=ov)
        warm = load(overrides=[*ov, "nodes=2", "hosts=1"])
        for m in methods:
            run_method(warm, m)
    except ConfigError as e:
        print(f"bench_sequence: error: {e}", file=sys.stderr)
        return 2
    if sc.fidelity.enabled:
        ideal_run(sc)
    print(f"N={a.nodes}, {a.duration:g} s simulated per run, methods {','.join(methods)} in "
          f"turn, {a.runs} runs in one process; load at start {os.getloadavg()[0]:.2f}")
    print(f"{'run':>4s} {'method':>8s} {'CPU s':>7s} {'user':>7s} {'sys':>7s} {'faults':>7s} "
          f"{'RSS MB':>7s}  aoi_mean ms")
    cpu: list[float] = []
    for i in range(a.runs):
        m = methods[i % len(methods)]
        r0, c0 = resource.getrusage(resource.RUSAGE_SELF), time.process_time()
        out = run_method(sc, m)
        c1, r1 = time.process_time(), resource.getrusage(resource.RUSAGE_SELF)
        cpu.append(c1 - c0)
        print(f"{i:4d} {m:>8s} {c1 - c0:7.3f} {r1.ru_utime - r0.ru_utime:7.3f} "
              f"{r1.ru_stime - r0.ru_stime:7.3f} {r1.ru_minflt - r0.ru_minflt:7d} "
              f"{r1.ru_maxrss / 1024:7.0f}  {out['metrics']['aoi_mean']!r}")
    med = statistics.median(cpu)
    print(f"median {med:.3f} CPU s per run = {med / a.duration:.3f} CPU s per simulated s; "
          f"load at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
