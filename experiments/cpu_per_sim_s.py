#!/usr/bin/env python
"""CPU seconds per simulated second of one method run, unprofiled, and a digest of its metrics.

Builds the scenario like ``profile_run.py`` (defaults + ``--set`` overrides, 20 nodes
per host), runs a two-node 0.5 s warm-up of the same kind untimed (imports, numba cache
loading), then times one ``run.run()`` with ``time.process_time`` (CPU time of this
process, so time descheduled on a shared machine is not counted). The metrics digest
lets interleaved A/B runs of two source trees check that the results are identical.

Usage::

    python experiments/cpu_per_sim_s.py --nodes 1000 --duration 3 --method bides
    python experiments/cpu_per_sim_s.py --method none --set commands.enabled=false
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=3.0)
    p.add_argument("--method", default="bides")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args(argv)
    from sigma_des.config import load
    from sigma_des.events.cohort import make_run
    from sigma_des.factory import make_behaviour, make_dynamics

    ov = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
          f"warmup={min(0.5, a.duration / 4)}", *a.set]
    sc = load(overrides=ov)
    warm = load(overrides=[*ov, "nodes=2", "hosts=1", "duration=0.5", "warmup=0.1"])
    run, _ = make_run(warm.run_spec(), a.method, make_dynamics(warm), make_behaviour(warm))
    run.run()
    run, fallback = make_run(sc.run_spec(), a.method, make_dynamics(sc), make_behaviour(sc))
    c = time.process_time()
    out = run.run()
    cpu = time.process_time() - c
    blob = json.dumps(out["metrics"], sort_keys=True, default=str).encode()
    print(f"{a.method} N={a.nodes} {a.duration:g} s: {cpu / a.duration:.4f} CPU-s/s; "
          f"engine {'events (' + fallback + ')' if fallback else 'cohort'}; "
          f"metrics {hashlib.sha1(blob).hexdigest()[:12]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
