#!/usr/bin/env python
"""Where one method run spends its CPU time: a cProfile of the engine, CPU-clocked.

Builds the scenario (defaults + ``--set`` overrides, 20 nodes per host), runs a
two-node 0.5 s warm-up of the same kind untimed (imports, numba cache loading), then
profiles one run of ``--method`` with ``time.process_time`` as the profiler clock
(so time the process spends descheduled on a shared machine is not counted) and
prints the CPU seconds per simulated second and the top functions by own time with
their share. Compiled (numba) kernels appear as single entries (``advance`` = the
cohort core's event loop, ``step_kernel`` = the aircraft step).

Usage::

    python experiments/profile_run.py --nodes 1000 --duration 3 --method bides
    python experiments/profile_run.py --quick      # 10 nodes, 0.3 s (tests)
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=3.0)
    p.add_argument("--method", default="bides")
    p.add_argument("--top", type=int, default=25, help="functions listed")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--quick", action="store_true", help="10 nodes, 0.3 s (for tests)")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration = 10, 0.3
    from sigma_des.config import load
    from sigma_des.errors import ConfigError
    from sigma_des.events.cohort import make_run
    from sigma_des.factory import make_behaviour, make_dynamics

    ov = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
          f"warmup={min(0.5, a.duration / 4)}", *a.set]
    try:
        sc = load(overrides=ov)
        warm = load(overrides=[*ov, "nodes=2", "hosts=1", "duration=0.5", "warmup=0.1"])
    except ConfigError as e:
        print(f"profile_run: error: {e}", file=sys.stderr)
        return 2
    run, _ = make_run(warm.run_spec(), a.method, make_dynamics(warm), make_behaviour(warm))
    run.run()
    run, fallback = make_run(sc.run_spec(), a.method, make_dynamics(sc), make_behaviour(sc))
    prof = cProfile.Profile(time.process_time)
    c = time.process_time()
    prof.enable()
    run.run()
    prof.disable()
    cpu = time.process_time() - c
    print(f"N={a.nodes} method={a.method} {a.duration:g} s simulated: {cpu:.3f} CPU s "
          f"(profiled), {cpu / a.duration:.3f} CPU s per simulated s; "
          f"engine {'events (' + fallback + ')' if fallback else 'cohort'}")
    st = pstats.Stats(prof)
    rows = sorted(st.stats.items(), key=lambda kv: -kv[1][2])  # type: ignore[attr-defined]
    total = sum(v[2] for _k, v in rows) or 1.0
    print(f"{'own s':>8s} {'share':>6s} {'calls':>8s}  function")
    for (file, line, fn), (_cc, nc, tt, _ct, _callers) in rows[: a.top]:
        where = file.rsplit("/", 2)[-1] if "/" in file else file
        print(f"{tt:8.3f} {100 * tt / total:5.1f}% {nc:8d}  {fn} ({where}:{line})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
