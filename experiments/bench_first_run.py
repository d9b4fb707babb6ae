#!/usr/bin/env python
"""First-run cost: a cold ``compare`` against ``sigma-des warmup`` plus a warm ``compare``.

Each step runs in a child process; ``cold`` and ``warmup`` each get a fresh, empty
``NUMBA_CACHE_DIR`` (``after`` reuses the warm-up's), and the ideal-run cache is off
(``SIGMA_DES_CACHE_DIR=off``), so every figure includes what a fresh install pays.
Per step it prints wall seconds and the child's CPU seconds (user + sys, from
``getrusage(RUSAGE_CHILDREN)``: the figure a shared machine does not inflate), and for
the cold step the compile time per kernel (numba ``numba:compile`` events, outermost
compilations only).

Usage::

    python experiments/bench_first_run.py                 # default scenario, duration 1 s
    python experiments/bench_first_run.py --jobs 2 --set nodes=1000
    python experiments/bench_first_run.py --quick         # warm cache, tiny run (tests)

Timing figures depend on the machine; nothing here asserts on them.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

#: Child code of the ``cold`` and ``after`` steps: one compare, compile events recorded.
CHILD = """
import json, sys
from numba.core import event
from sigma_des.api import compare
from sigma_des.config import load
sc = load(None, json.loads(sys.argv[1]))
with event.install_recorder("numba:compile") as rec:
    compare(sc, progress=False)
tot, stack = {}, []
for ts, ev in rec.buffer:
    f = ev.data["dispatcher"].py_func
    name = f.__module__.rsplit(".", 1)[-1] + "." + f.__qualname__
    if ev.is_start:
        stack.append((name, ts))
    else:
        n, t0 = stack.pop()
        if not stack:
            tot[n] = tot.get(n, 0.0) + ts - t0
print(json.dumps(tot))
"""


def _child(argv: list[str], env: dict[str, str]) -> tuple[float, float, str]:
    """Run ``argv``; return (wall s, child CPU s, stdout)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, r.stdout


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario override (repeatable; default: duration 1 s)")
    p.add_argument("--jobs", type=int, default=2, help="sigma-des warmup --jobs")
    p.add_argument("--quick", action="store_true",
                   help="keep the current numba cache and run 0.2 s on 4 nodes (for tests)")
    a = p.parse_args(argv)
    if a.jobs < 1:
        p.error(f"--jobs must be >= 1, got {a.jobs}")
    sets = ["duration=1", "warmup=0.2", *a.set]
    if a.quick:
        sets = ["nodes=4", "duration=0.2", "warmup=0.05", *a.set]
    env = {**os.environ, "SIGMA_DES_CACHE_DIR": "off"}
    py = sys.executable
    rows: list[tuple[str, float, float]] = []
    with tempfile.TemporaryDirectory() as d1, tempfile.TemporaryDirectory() as d2:
        cold_env = env if a.quick else {**env, "NUMBA_CACHE_DIR": d1}
        warm_env = env if a.quick else {**env, "NUMBA_CACHE_DIR": d2}
        w, c, out = _child([py, "-c", CHILD, json.dumps(sets)], cold_env)
        rows.append(("cold compare", w, c))
        kernels = json.loads(out.strip().splitlines()[-1])
        w, c, out = _child([py, "-m", "sigma_des.cli", "warmup", "--jobs", str(a.jobs)],
                           warm_env)
        rows.append((f"warmup --jobs {a.jobs}", w, c))
        units = [ln for ln in out.splitlines() if "kernels compiled" in ln]
        w, c, _ = _child([py, "-c", CHILD, json.dumps(sets)], warm_env)
        rows.append(("compare after warm-up", w, c))
    print(f"first-run cost; overrides {sets}; load average {os.getloadavg()[0]:.1f} at the end")
    print(f"{'step':24s} {'wall s':>8s} {'CPU s':>8s}")
    for name, w, c in rows:
        print(f"{name:24s} {w:8.2f} {c:8.2f}")
    print("warm-up units:")
    for ln in units:
        print("  " + ln)
    total = sum(kernels.values())
    print(f"cold compile per kernel (outermost; total {total:.2f} s wall):")
    for name, s in sorted(kernels.items(), key=lambda kv: -kv[1]):
        print(f"  {s:7.2f} s  {100 * s / total if total else 0:5.1f} %  {name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
