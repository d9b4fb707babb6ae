#!/usr/bin/env python
"""Peak memory of a command and every process it starts (the ``compare --jobs`` workers).

``/usr/bin/time -v`` reports the largest *single* process of a command (its
``ru_maxrss`` covers waited-for children one by one, never their sum). This script
runs the command, samples ``/proc`` every ``--interval`` seconds for the command's
process tree and prints, at the end: wall and CPU seconds (the children's
``user+sys``), each process's peak RSS, the peak of the tree's summed RSS (counts
pages the forked workers share with their parent once per process) and the peak of
the summed PSS (``/proc/PID/smaps_rollup``: a shared page split between its sharers,
so the sum is the tree's real footprint). Linux only.

Usage::

    python experiments/tree_rss.py -- sigma-des compare --set nodes=1000 --set hosts=50 \
        --set duration=60 --jobs 2 --no-progress
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Any


def children(pid: int) -> list[int]:
    """Direct children of ``pid`` (via /proc/PID/task/*/children)."""
    out: list[int] = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as fh:
                out += [int(x) for x in fh.read().split()]
    except OSError:
        pass
    return out


def tree(pid: int) -> list[int]:
    """``pid`` and all its descendants."""
    todo, seen = [pid], []
    while todo:
        p = todo.pop()
        seen.append(p)
        todo += children(p)
    return seen


def memory_kb(pid: int) -> tuple[int, int]:
    """(RSS, PSS) of ``pid`` in kB (0, 0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            vals = {ln.split(":")[0]: int(ln.split()[1]) for ln in fh if ln.endswith("kB\n")}
        return vals.get("Rss", 0), vals.get("Pss", 0)
    except (OSError, ValueError, IndexError):
        return 0, 0


def load1() -> float:
    """The 1-minute load average."""
    with open("/proc/loadavg") as fh:
        return float(fh.read().split()[0])


@dataclass
class Watched:
    """What :func:`watch` saw of a process tree: peaks in kB, the load's maximum."""

    peak: dict[int, int] = field(default_factory=dict)
    sum_rss: int = 0
    sum_pss: int = 0
    load_max: float = 0.0


def watch(proc: subprocess.Popen[Any], interval: float) -> Watched:
    """Sample ``proc``'s tree every ``interval`` s until it exits."""
    w = Watched(load_max=load1())
    while proc.poll() is None:
        rss_t = pss_t = 0
        for pid in tree(proc.pid):
            rss, pss = memory_kb(pid)
            w.peak[pid] = max(w.peak.get(pid, 0), rss)
            rss_t += rss
            pss_t += pss
        w.sum_rss, w.sum_pss = max(w.sum_rss, rss_t), max(w.sum_pss, pss_t)
        w.load_max = max(w.load_max, load1())
        time.sleep(interval)
    return w


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--interval", type=float, default=0.25)
    p.add_argument("cmd", nargs=argparse.REMAINDER)
    a = p.parse_args(argv)
    cmd = a.cmd[1:] if a.cmd[:1] == ["--"] else a.cmd
    if not cmd:
        p.error("no command")
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd)
    w = watch(proc, a.interval)
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = ru.ru_utime + ru.ru_stime
    print(f"tree_rss: exit {proc.returncode}, wall {wall:.1f} s, CPU {cpu:.1f} s"
          f" (user {ru.ru_utime:.1f}), largest process (time -v) {ru.ru_maxrss / 1024:.0f} MB",
          file=sys.stderr)
    order = sorted(w.peak, key=lambda q: -w.peak[q])
    print("tree_rss: per-process peak RSS MB: " + ", ".join(
        f"{q}{' (parent)' if q == proc.pid else ''} {w.peak[q] / 1024:.0f}" for q in order),
        file=sys.stderr)
    print(f"tree_rss: peak summed RSS {w.sum_rss / 1024:.0f} MB, peak summed PSS "
          f"{w.sum_pss / 1024:.0f} MB (sampled every {a.interval:g} s); 1-minute load "
          f"average up to {w.load_max:.2f}", file=sys.stderr)
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
