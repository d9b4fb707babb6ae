"""Agent-steps per second of the vectorised swarm env, per method, and memory per scene.

The formation task with 11 nodes (a scripted leader and 10 learning agents), the
env's default scenario otherwise (point mass, 50 Hz triggers, 20 Hz alignment, a
decision every 2nd tick = 5 physics frames per decision, datagram QoS 0, cohort
engine), for 1, 10 and 500 scenes and each alignment method. An agent-step is one
agent's decision: ``scenes x 10`` per env step. Times are the thread's CPU time
(``time.thread_time``, one core), the best of ``--reps`` batches of ``--steps``
steps after a reset (reset excluded). ``--variant const`` also runs every case with
a constant compute time (no per-frame random draws). Memory per scene: Python heap
allocated by ``reset`` (tracemalloc) of a batch of ``--mem-scenes`` scenes / scenes.
For reference, the same scenario run on its own by the simulator (no env; the
built-in ``follow`` behaviour sends the commands): CPU ms per decision period.

``--study``: instead, the delay study's configuration (``tight`` task, 5 nodes = 4
agents, BiDES at 200 ms with 10 % loss, and ``perfect``; the study's env arguments, so
without simulator metrics, ``metrics=False``; ``--with-metrics``: the env's default,
with them), 4 and 64 scenes, random actions, against the targets (>= 50 000
agent-steps per CPU-s at 64 scenes, >= 20 000 at 4). The headline is the steady state
of the study's training episodes (at most 50 steps; random actions end most earlier):
``--steady`` steps (default 100) timed after 60, episode restarts included at their
real rate; beside it the best of ``--reps`` batches of ``--steps`` within episodes
(restarts excluded). Memory: the process's resident
set (``VmRSS``) grown by building and resetting ``--fit`` scenes (default 512), per
scene and in all (target: 512 scenes in 2 GB). For normalisation across machines it
also prints the CPU seconds per simulated second of the in-repo process-per-message
SimPy baseline (``sigma_lab.reference.process_model``) on a fixed scenario (50 nodes,
stream transport, method ``none``, 2 s), run in the same
process: divide an env figure by it to compare machines. Then ``--ppo`` agent-steps
(default 204 800; 0: skip) of one PPO training with the study's settings on its BiDES
cell, wall and CPU, projected to the study's 2 x 10^6 agent-steps per policy (target:
<= 15 minutes wall, one training per core).

The measuring code is ``sigma_lab.studies.env_bench``.

Usage: ``python experiments/bench_env.py [--quick] [--study] [--out out/env]``
"""

from __future__ import annotations

import argparse
import csv
import json
import os
from importlib.util import find_spec
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from sigma_lab.studies.env_bench import (  # noqa: E402
    AGENTS,
    TARGET_500,
    make,
    memory,
    plain,
    ppo,
    speed,
    study,
)

from sigma_des import __version__  # noqa: E402
from sigma_des.config import METHODS  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table, write CSV and JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 and 2 scenes, few steps")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--mem-scenes", type=int, default=50)
    ap.add_argument("--variant", choices=["default", "const", "both"], default="both")
    ap.add_argument("--study", action="store_true",
                    help="the delay study's configuration (see the module docstring)")
    ap.add_argument("--steady", type=int, default=100,
                    help="--study: steps of the steady-state window")
    ap.add_argument("--fit", type=int, default=512, help="--study: scenes of the memory check")
    ap.add_argument("--ppo", type=int, default=204_800,
                    help="--study: agent-steps of the timed PPO training (0: none)")
    ap.add_argument("--with-metrics", action="store_true",
                    help="--study: the scenes' runs collect the simulator's metrics")
    ap.add_argument("--out", default="out/env")
    args = ap.parse_args(argv)
    for key in ("steps", "reps", "steady", "fit", "mem_scenes"):
        if getattr(args, key) < 1:
            ap.error(f"--{key.replace('_', '-')}: must be >= 1, got {getattr(args, key)}")
    if args.ppo < 0:
        ap.error(f"--ppo: must be >= 0 (0: no PPO timing), got {args.ppo}")
    if args.study:
        res = study((1, 2) if args.quick else (4, 64), 2 if args.quick else args.steps,
                    1 if args.quick else args.reps, 4 if args.quick else args.fit,
                    args.with_metrics, steady=2 if args.quick else args.steady)
        if args.ppo and find_spec("stable_baselines3") is None:
            print("PPO timing skipped: stable-baselines3 is not installed (the `learn` "
                  "extra: pip install 'sigma-des[learn]')", flush=True)
        elif args.ppo:  # --quick: two rollouts of 8 steps on one scene
            res["ppo"] = (ppo(64, scenes=1, n_steps=8, batch=32) if args.quick
                          else ppo(args.ppo))
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "bench_study.json").write_text(json.dumps(
            {"version": __version__, **res, "quick": args.quick}, indent=2) + "\n")
        return 0
    sizes = (1, 2) if args.quick else (1, 10, 500)
    steps = 2 if args.quick else args.steps
    reps = 1 if args.quick else args.reps
    mem_scenes = 2 if args.quick else args.mem_scenes
    variants = ["default", "const"] if args.variant == "both" else [args.variant]
    make("none", 1, "default").reset(seed=1)  # compile/warm the kernels outside the timing
    rows = []
    for variant in variants:
        for scenes in sizes:
            for method in METHODS:
                r = speed(method, scenes, variant, steps if scenes < 500 else max(2, steps // 2),
                          reps)
                rows.append(r)
                goal = ""
                if scenes == 500:
                    met = "met" if r["agent_steps_per_s"] >= TARGET_500 else "not met"
                    goal = f"  target >= {TARGET_500:,}: {met}; load {os.getloadavg()[0]:.1f}"
                print(f"{variant:8s} {method:9s} {scenes:4d} scenes: "
                      f"{r['agent_steps_per_s']:9.0f} agent-steps/s "
                      f"({r['ms_per_scene_step']:.3f} ms per scene-step){goal}", flush=True)
    plains = [plain(m, 20 if args.quick else 500) for m in METHODS]
    for p in plains:
        print(f"plain run {p['method']:9s}: {p['ms_per_decision']:.3f} ms per decision period "
              "(the simulator alone, same scenario, built-in behaviour)", flush=True)
    mem = {m: memory(m, mem_scenes) for m in METHODS}
    for m, b in mem.items():
        print(f"memory per scene ({m}): {b / 1024:.1f} KiB", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "bench.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*rows[0], "version"])
        w.writeheader()
        for r in rows:
            w.writerow({**r, "version": __version__})
    (out / "bench.json").write_text(json.dumps(
        {"version": __version__, "agents": AGENTS, "rows": rows, "plain": plains,
         "memory_bytes_per_scene": mem, "mem_scenes": mem_scenes, "quick": args.quick},
        indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
