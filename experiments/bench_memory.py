#!/usr/bin/env python
"""Peak memory of the default comparison, per method and per process (issue 27: < 500 MB).

Three parts:

* per method (``--methods``): ``sigma-des compare --methods M`` in a child process,
  its process tree sampled every ``--interval`` s (``tree_rss.py``): the largest
  process's peak RSS, the child's own ``peak_rss_mb`` (``wall.csv``), wall and CPU
  seconds, and the 1-minute load average at the start, at the end and its maximum;
* ``--whole``: the whole comparison (all four methods, ``--jobs``) in one command:
  every process's peak;
* ``--detail M``: one run of method M in this process: RSS and the compiled core's
  event table every ``--every`` simulated s, and at the end every state array of
  1 MB or more (what bounds the memory).

Nothing is asserted: the figures depend on the machine and its load.

Usage::

    python experiments/bench_memory.py                     # N = 1000, 60 s, 4 methods + whole
    python experiments/bench_memory.py --methods none,hlc --no-whole --detail none
    python experiments/bench_memory.py --quick             # N = 10, 1 s (tests)
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tree_rss import load1, watch

METHODS = ("none", "hlc", "lockstep", "bides")


@dataclass
class Sample:
    """One command's figures: peak RSS MB (largest process, parent, each worker), wall and
    CPU seconds, the 1-minute load average at its start and end and its maximum."""

    largest: float
    parent: float
    workers: list[float]
    wall: float
    cpu: float
    load: tuple[float, float, float]

    def load_text(self) -> str:
        return "{:.2f} / {:.2f} / {:.2f}".format(*self.load)


def sampled(cmd: list[str], interval: float) -> Sample:
    """Run ``cmd`` (its process tree sampled every ``interval`` s)."""
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    la0, t0 = load1(), time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
    w = watch(proc, interval)
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise SystemExit(f"bench_memory: {' '.join(cmd)} exited {proc.returncode}")
    cpu = ru.ru_utime + ru.ru_stime - ru0.ru_utime - ru0.ru_stime
    mb = {p: v / 1024 for p, v in w.peak.items()}
    return Sample(max(mb.values(), default=0.0), mb.get(proc.pid, 0.0),
                  sorted((v for p, v in mb.items() if p != proc.pid), reverse=True),
                  wall, cpu, (la0, load1(), w.load_max))


def compare_cmd(a: argparse.Namespace, methods: str, jobs: int, out: Path) -> list[str]:
    sets = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
            *a.set]
    return [sys.executable, "-m", "sigma_des.cli", "compare", *(x for s in sets for x in
            ("--set", s)), "--methods", methods, "--jobs", str(jobs), "--no-plots",
            "--no-progress", "--out", str(out)]


def per_method(a: argparse.Namespace, tmp: Path) -> None:
    print("method | largest process MB | wall.csv peak_rss_mb | wall s | CPU s | "
          "load1 start / end / max")
    for m in a.methods.split(","):
        r = sampled(compare_cmd(a, m, 1, tmp / m), a.interval)
        with open(tmp / m / "wall.csv") as fh:
            own = max(float(row["value"]) for row in csv.DictReader(fh)
                      if row["metric"] == "peak_rss_mb")
        print(f"{m} | {r.largest:.0f} | {own:.0f} | {r.wall:.1f} | {r.cpu:.1f} | "
              f"{r.load_text()}", flush=True)


def whole(a: argparse.Namespace, tmp: Path) -> None:
    r = sampled(compare_cmd(a, ",".join(METHODS), a.jobs, tmp / "whole"), a.interval)
    workers = ", ".join(f"{v:.0f}" for v in r.workers)
    print(f"whole compare --jobs {a.jobs}: workers' peak RSS MB {workers}; parent "
          f"{r.parent:.0f}; wall {r.wall:.1f} s, CPU {r.cpu:.1f} s; load1 start / end / max "
          f"{r.load_text()}")


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def detail(a: argparse.Namespace) -> None:
    """One run in this process: the event table as it grows, the largest arrays at the end."""
    from sigma_des.config import load
    from sigma_des.events.cohort import make_run
    from sigma_des.events.fast import codes as CO
    from sigma_des.events.fast import layout as L
    from sigma_des.events.fast.driver import CompiledCore
    from sigma_des.factory import make_behaviour, make_dynamics

    sc = load(overrides=[f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}",
                         f"duration={a.duration}", *a.set])
    run, why = make_run(sc.run_spec(), a.detail, make_dynamics(sc), make_behaviour(sc))
    core = run.core
    if not isinstance(core, CompiledCore):
        raise SystemExit(f"bench_memory: {a.detail} runs per message ({why})")
    nxt = [a.every]

    def table() -> str:
        cap = core.array("ev_int").shape[0]
        iv = core.array("ints")
        live = cap - int(iv[CO.I_FREE])
        slot = sum(core.array(f.name).nbytes for f in L.FIELDS if f.shape[:1] in (("cap",),
                   ("arena",))) / cap
        rows = core.array("pool_free").size
        row = (core.array("pool").nbytes + core.array("pool_free").nbytes) / max(rows, 1)
        return (f"event table {cap} slots ({slot:.0f} B each), {live} in flight; payload pool "
                f"{rows} rows ({row:.0f} B each), {rows - int(iv[CO.I_PFREE])} in use")

    last: list[tuple[float, int, str, tuple[str | int, ...]]] = []

    def tick(t: float) -> None:
        if t + 1e-9 >= nxt[0]:
            nxt[0] += a.every
            print(f"  t = {t:g} s: RSS {rss_mb():.0f} MB, {table()}", flush=True)
        if t >= sc.duration:  # the last call, before the run lets go of its event table
            last[:] = [(resident(core.array(f.name)), core.array(f.name).nbytes, f.name,
                        f.shape) for f in L.FIELDS]
            print(f"  at the end of the simulation: RSS {rss_mb():.0f} MB, {table()}")

    run.run(tick)
    print(f"{a.detail} at the end: RSS {rss_mb():.0f} MB, peak "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB; the core's "
          "arrays of 1 MB or more at the end of the simulation (resident / allocated):")
    for res, nbytes, name, shape in sorted(last, reverse=True):
        if nbytes >= 2**20:
            print(f"  {res:7.1f} / {nbytes / 2**20:7.1f} MB  {name} {shape}")


def resident(arr: Any) -> float:
    """Resident MB of ``arr``'s pages (``mincore``: pages never touched are not resident)."""
    page = os.sysconf("SC_PAGE_SIZE")
    lo = arr.ctypes.data // page * page
    n = (arr.ctypes.data + arr.nbytes - lo + page - 1) // page
    if arr.nbytes == 0:
        return 0.0
    vec = (ctypes.c_ubyte * n)()
    if LIBC.mincore(ctypes.c_void_p(lo), ctypes.c_size_t(n * page), vec) != 0:
        return float("nan")
    return sum(v & 1 for v in vec) * page / 2**20


LIBC = ctypes.CDLL(None, use_errno=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--methods", default=",".join(METHODS))
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--no-whole", dest="whole", action="store_false")
    p.add_argument("--detail", metavar="METHOD", help="also one in-process run of METHOD")
    p.add_argument("--every", type=float, default=10.0, help="simulated s between lines")
    p.add_argument("--interval", type=float, default=0.25, help="s between RSS samples")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--quick", action="store_true", help="N = 10, 1 s (for tests)")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration, a.every, a.interval = 10, 1.0, 0.5, 0.05
        a.set = [*a.set, "warmup=0.2", "fidelity.enabled=false"]
    print(f"bench_memory: N = {a.nodes}, {a.duration:g} s, {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as d:
        if a.methods:
            per_method(a, Path(d))
        if a.whole:
            whole(a, Path(d))
    if a.detail:
        detail(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
