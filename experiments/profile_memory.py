#!/usr/bin/env python
"""What one method run keeps in memory as it goes: tracemalloc snapshots per simulated second.

Builds the scenario (defaults + ``--set`` overrides, 20 nodes per host), runs a
two-node warm-up of the same kind (imports, numba cache loading), then runs
``--method`` with :mod:`tracemalloc` tracing and, at every ``--every`` simulated
seconds (the run's progress callback), prints the traced Python heap, the process
RSS and the source lines whose live allocations grew most since the first
snapshot. At the end it prints the same for the finished result dict (what a
``compare`` keeps of the run). numpy arrays are traced (numpy reports its buffers to
tracemalloc); memory that numba kernels hold in the run's state arrays is allocated
by numpy too.

Usage::

    python experiments/profile_memory.py --nodes 1000 --duration 20 --method none \
        --set fidelity.enabled=false
    python experiments/profile_memory.py --quick      # 10 nodes, 0.6 s (tests)
"""

from __future__ import annotations

import argparse
import resource
import sys
import tracemalloc
from typing import Any


def rss_mb() -> float:
    """Current resident set size of this process (MB), from /proc (peak where missing)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
        import os

        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):  # pragma: no cover - not Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def growth(base: tracemalloc.Snapshot, snap: tracemalloc.Snapshot, top: int) -> list[str]:
    """The ``top`` source lines whose live allocations grew most from ``base`` to ``snap``."""
    rows = snap.compare_to(base, "lineno")
    rows.sort(key=lambda s: -s.size_diff)
    out = []
    for s in rows[:top]:
        fr = s.traceback[0]
        out.append(f"    {s.size_diff / 2**20:+8.2f} MB  {s.count_diff:+9d} blocks  "
                   f"{fr.filename.rsplit('sigma_des/', 1)[-1]}:{fr.lineno}")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--method", default="none")
    p.add_argument("--every", type=float, default=5.0, help="simulated s between snapshots")
    p.add_argument("--top", type=int, default=8, help="source lines listed per snapshot")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--quick", action="store_true", help="10 nodes, 0.6 s (for tests)")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration, a.every = 10, 0.6, 0.3
    from sigma_des.api import run_method
    from sigma_des.config import load
    from sigma_des.errors import ConfigError

    ov = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
          f"warmup={min(1.0, a.duration / 4)}", *a.set]
    try:
        sc = load(overrides=ov)
        warm = load(overrides=[*ov, "nodes=2", "hosts=1", "duration=0.5", "warmup=0.1",
                               "fidelity.enabled=false"])
    except ConfigError as e:
        print(f"profile_memory: error: {e}", file=sys.stderr)
        return 2
    run_method(warm, a.method)
    tracemalloc.start()
    base = tracemalloc.take_snapshot()
    print(f"N={a.nodes} method={a.method} {a.duration:g} s: start traced "
          f"{tracemalloc.get_traced_memory()[0] / 2**20:.1f} MB, RSS {rss_mb():.1f} MB")
    next_t = [a.every]

    def tick(t: float) -> None:
        if t + 1e-9 < next_t[0]:
            return
        next_t[0] += a.every
        snap = tracemalloc.take_snapshot()
        print(f"  t={t:g} s: traced {tracemalloc.get_traced_memory()[0] / 2**20:.1f} MB, "
              f"RSS {rss_mb():.1f} MB; grown since start:")
        print("\n".join(growth(base, snap, a.top)))

    out: dict[str, Any] = run_method(sc, a.method, tick)
    snap = tracemalloc.take_snapshot()
    print(f"  end (result dict built): traced {tracemalloc.get_traced_memory()[0] / 2**20:.1f}"
          f" MB, peak traced {tracemalloc.get_traced_memory()[1] / 2**20:.1f} MB, "
          f"RSS {rss_mb():.1f} MB; grown since start:")
    print("\n".join(growth(base, snap, a.top)))
    kept = sum(v.nbytes for v in out["timeseries"].values())
    if "fidelity" in out:
        kept += sum(v.nbytes for v in out["fidelity"].values())
    print(f"  result: time series + fidelity series {kept / 2**20:.2f} MB, "
          f"{len(out['metrics'])} metrics; aoi_mean {out['metrics']['aoi_mean']!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
