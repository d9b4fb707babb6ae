#!/usr/bin/env python
"""Where a step of the learning env spends its CPU time: a cProfile of ``SwarmVec``.

The delay study's configuration (``tight`` task, 5 nodes = 4 agents; ``--cond``
``bides@200ms``: BiDES at 200 ms with 10 % loss, or ``perfect``), ``--scenes`` scenes,
random actions, the study's env arguments (no simulator metrics; ``--with-metrics``:
the env's default). After ``--warm`` untimed steps it times ``--steps`` steps
unprofiled (CPU time of this thread: agent-steps per CPU-s and µs per scene-step),
then profiles the same number of steps with ``time.process_time`` as the profiler's
clock and prints the own time per source file (a module's share of the profiled
time), then the top functions by own time. Profiling inflates Python-heavy code, so
the shares rank the costs; the unprofiled figure is the speed. Compiled (numba)
kernels appear as single entries (``loop.py:advance`` = the message core, its entry
points called by handle counted as ``loop.py``'s).

Usage::

    python experiments/profile_env.py --scenes 64 --steps 20
    python experiments/profile_env.py --cond perfect --scenes 4 --steps 100
    python experiments/profile_env.py --quick      # 2 scenes, 2 steps (tests)
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import re
import time
from collections import Counter
from typing import Any

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from sigma_lab.studies.delay import env_kwargs  # noqa: E402

from sigma_des.env import SwarmVec  # noqa: E402

#: the message core's entry points the engine calls by handle, without numba's dispatch,
#: as the profiler names them (built-ins of ``fast/handle.py``): the loop's own code
BY_HANDLE = re.compile(r"<built-in method sigma_des\.events\.fast\.handle\.\w+>")


def _short(path: str, fn: str = "") -> str:
    """A source path from its package folder on (``sigma_des/...``, ``numpy/...``); the
    loop's entry points called by handle, ``loop.py``'s."""
    if path == "~" and BY_HANDLE.fullmatch(fn):
        return "sigma_des/events/fast/loop.py"
    for mark in ("sigma_des/", "site-packages/"):
        if mark in path:
            return path[path.index(mark) + (0 if mark == "sigma_des/" else len(mark)):]
    return path


def profile(cond: str, scenes: int, steps: int, warm: int, metrics: bool,
            top: int) -> dict[str, Any]:
    """Time and profile ``steps`` env steps; returns the figures and the per-file shares."""
    env = SwarmVec(n_scenes=scenes, **{**env_kwargs(cond, 5, 10_000, 0.1), "metrics": metrics})
    env.reset(seed=1)
    acts = np.random.default_rng(0).uniform(-1, 1, (warm + 2 * steps, scenes, env.n_agents, 3))
    for k in range(warm):
        env.step(acts[k])
    t = time.thread_time()
    for k in range(warm, warm + steps):
        env.step(acts[k])
    cpu = time.thread_time() - t
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    for k in range(warm + steps, warm + 2 * steps):
        env.step(acts[k])
    prof.disable()
    stats = pstats.Stats(prof)
    own: Counter[str] = Counter()
    for (path, _line, fn), row in stats.stats.items():  # type: ignore[attr-defined]
        own[_short(path, fn)] += row[2]
    total = sum(own.values()) or 1.0
    scene_steps = scenes * steps
    print(f"{cond}, {scenes} scenes, metrics {metrics}: "
          f"{scene_steps * env.n_agents / cpu:.0f} agent-steps per CPU-s, "
          f"{cpu / scene_steps * 1e6:.0f} µs per scene-step (unprofiled); "
          f"load {os.getloadavg()[0]:.1f}")
    print(f"own time per file ({total:.2f} s profiled):")
    for name, sec in own.most_common(top):
        print(f"  {sec / total * 100:5.1f} %  {name}")
    stats.sort_stats("tottime").print_stats(top)
    return {"agent_steps_per_s": scene_steps * env.n_agents / cpu,
            "us_per_scene_step": cpu / scene_steps * 1e6,
            "files": {k: v / total for k, v in own.items()}}


def main(argv: list[str] | None = None) -> int:
    """Parse the options and print the profile."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cond", choices=["bides@200ms", "perfect"], default="bides@200ms")
    ap.add_argument("--scenes", type=int, default=64)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--warm", type=int, default=5, help="untimed steps first")
    ap.add_argument("--top", type=int, default=25, help="rows of each table")
    ap.add_argument("--with-metrics", action="store_true",
                    help="the scenes' runs collect the simulator's metrics")
    ap.add_argument("--quick", action="store_true", help="2 scenes, 2 steps")
    a = ap.parse_args(argv)
    for key in ("scenes", "steps"):
        if getattr(a, key) < 1:
            ap.exit(2, f"--{key}: must be >= 1, got {getattr(a, key)}\n")
    if a.warm < 0:
        ap.exit(2, f"--warm: must be >= 0, got {a.warm}\n")
    if a.quick:
        a.scenes, a.steps, a.warm, a.top = 2, 2, 1, 5
    profile(a.cond, a.scenes, a.steps, a.warm, a.with_metrics, a.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
