"""Does training on the aligned, delayed view beat training with perfect information, under delay?

Task ``tight`` (fast manoeuvring leader, 6 m slots, observations with per-neighbour
age and velocity; ``sigma_des.env.tasks.TightTask``). Training conditions, equal
budgets, seeds ``0..seeds-1`` each:

* ``perfect``: the true current state over an ideal network (what peer envs give);
* ``delay`` cells: host links with latency normal(L, L/5) and Bernoulli loss
  (``--loss``), for every delay level L (``--delays``) and alignment method
  (``--methods``); agents observe that method's aligned view.

Learner: ``cem`` (zero-dependency cross-entropy method over a shared linear policy,
``sigma_des.env.learn``) or ``ppo`` (``sigma_des.env.ppo``: Stable-Baselines3 PPO with
observation and reward normalisation, ``--policy mlp``, ``stack`` = frame-stacked MLP
or ``lstm`` = sb3-contrib RecurrentPPO; the ``learn`` extra). Every trained policy,
the untrained (zero) policy and the two hand-written controllers
(``sigma_des.env.controllers``) are evaluated on the same held-out episodes (root
seed ``--eval-seed``) of every delay cell and of ``perfect``.
Per delay cell: mean ± 95 % CI over seeds (t distribution) and a paired one-sided
test over seeds of "delay-trained beats perfect-trained under that delay" (paired t
test and Wilcoxon signed-rank, ``scipy.stats``).

Outputs (``--out``): ``history.csv`` (learning curves), ``eval.csv`` (per policy and
evaluation condition), ``stats.csv`` (per delay cell), ``summary.json`` (also the
``perfect`` comparison with the hand-written controllers), ``summary.md`` (the tables
and what they support, in words), ``learning_curves.png``, ``eval.png``, written after
every seed.

Resumable (``--checkpoints``, default ``<out>/checkpoints``): PPO saves every policy
there as it trains and a rerun goes on from the save; a finished training (and its
evaluations) is recorded there and not redone. ``--ppo-wall`` bounds one training's
wall time per invocation (rerun to continue). Progress: a line every ``--progress``
rollouts (agent-steps, reward, rate, ETA) and one per finished training.

``--jobs N``: the seeds trained in ``N`` processes (round-robin shards under
``<out>/shards``, one checkpoint folder), merged into ``--out`` at the end.

``--full``: the full PPO study in one command (5 seeds; 50 and 200 ms; BiDES and
none; 2 x 10^6 agent-steps per policy on 16 scenes; ``--policy``, ``--delays`` and
``--methods`` kept, e.g. the recurrent policies at 200 ms only), outputs in
``out/env/delay_ppo_<policy>``; ``python experiments/make_docs_results.py --only delay
--work DIR`` runs it with ``--jobs 2`` and files it on the documentation's Learning page.
``--delays none``: ``perfect`` only. ``--ages-control``: then the ages-hidden control
(``train_ages_control.py``) on the finished study, its table appended to ``summary.md``.

Usage: ``python experiments/train_under_delay.py [--quick | --full] [--learner cem|ppo]
[--policy mlp|stack|lstm] [--seeds 5] [--out out/env/delay_study]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sigma_lab.studies.ages_control import add_to_study
from sigma_lab.studies.delay import cells
from sigma_lab.studies.delay_jobs import run_jobs
from sigma_lab.studies.delay_study import merge, run

OUT = "out/env/delay_study"


def _parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny scale (CEM, seconds)")
    ap.add_argument("--full", action="store_true", help="the full PPO study (docstring)")
    ap.add_argument("--learner", choices=("cem", "ppo"), default="cem")
    ap.add_argument("--policy", choices=("mlp", "stack", "lstm"), default="mlp", help="PPO")
    ap.add_argument("--n-stack", type=int, default=4, help="PPO stack: frames")
    ap.add_argument("--ppo-wall", type=float, default=None,
                    help="PPO: wall seconds per training in this invocation (rerun goes on)")
    ap.add_argument("--progress", type=int, default=10, help="PPO: rollouts per progress line")
    ap.add_argument("--train", default=None,
                    help="train only these conditions (comma list, e.g. perfect); every "
                         "trained policy is still evaluated as usual")
    ap.add_argument("--checkpoints", default=None,
                    help="resume folder (default <out>/checkpoints; '' = none)")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--delays", default=None,
                    help="mean host-link latencies (s; default 0.05,0.2; kept by --full)")
    ap.add_argument("--methods", default=None, help="default bides,none; kept by --full")
    ap.add_argument("--loss", type=float, default=0.1)
    ap.add_argument("--nodes", type=int, default=5)
    ap.add_argument("--max-steps", type=int, default=50)
    ap.add_argument("--eval-episodes", type=int, default=32)
    ap.add_argument("--eval-seed", type=int, default=10_000)
    ap.add_argument("--iterations", type=int, default=10, help="CEM")
    ap.add_argument("--population", type=int, default=8, help="CEM")
    ap.add_argument("--episodes", type=int, default=2, help="CEM: episodes per candidate")
    ap.add_argument("--ppo-steps", type=int, default=20_000, help="PPO agent-steps")
    ap.add_argument("--ppo-scenes", type=int, default=4)
    ap.add_argument("--ppo-n-steps", type=int, default=128)
    ap.add_argument("--ppo-batch", type=int, default=256)
    ap.add_argument("--seed-list", default=None,
                    help="train these seeds (comma list) instead of 0..seeds-1: a shard")
    ap.add_argument("--skip-baselines", action="store_true",
                    help="do not evaluate the untrained and hand-written policies (a shard)")
    ap.add_argument("--merge", nargs="+", default=None, metavar="DIR",
                    help="merge the outputs of shards (same settings) into --out; no training")
    ap.add_argument("--jobs", type=int, default=1,
                    help="train the seeds in this many processes, then merge (resumable)")
    ap.add_argument("--ages-control", action="store_true",
                    help="then run the ages-hidden control on the finished study "
                         "(train_ages_control.py): ages_control.csv/.json, summary.md")
    ap.add_argument("--out", default=OUT)
    a = ap.parse_args(argv)
    a.delays, a.methods = a.delays or "0.05,0.2", a.methods or "bides,none"
    if a.full:  # a given --delays / --methods stays: a part of the full study
        a.learner, a.seeds, a.nodes = "ppo", 5, 5
        a.max_steps, a.ppo_steps, a.ppo_scenes, a.ppo_n_steps, a.ppo_batch = (
            50, 2_000_000, 16, 64, 1024)
        if a.out == OUT:
            a.out = f"out/env/delay_ppo_{a.policy}"
    if a.quick:
        a.learner, a.seeds, a.delays, a.methods = "cem", 2, "0.2", "bides"
        a.nodes, a.max_steps, a.eval_episodes = 3, 10, 2
        a.iterations, a.population, a.episodes = 2, 4, 1
    for key in ("seeds", "nodes", "max_steps", "eval_episodes", "iterations", "population",
                "episodes", "ppo_steps", "ppo_scenes", "n_stack", "progress", "jobs"):
        if getattr(a, key) < 1 or (key == "nodes" and a.nodes < 2):
            ap.error(f"--{key.replace('_', '-')}: must be >= {2 if key == 'nodes' else 1}, "
                     f"got {getattr(a, key)}")
    if not 0 <= a.loss < 1:
        ap.error(f"--loss: must be in [0, 1), got {a.loss}")
    a.seed_ids = (list(range(a.seeds)) if a.seed_list is None
                  else [int(x) for x in a.seed_list.split(",")])
    if a.checkpoints is None:  # --full: model files outside the docs folder
        a.checkpoints = (f"out/env/delay_ppo_{a.policy}/checkpoints" if a.full
                         else f"{a.out}/checkpoints")
    a.delay_list = [] if a.delays == "none" else [float(x) for x in a.delays.split(",")]
    a.method_list = a.methods.split(",")
    a.train_list = None if a.train is None else a.train.split(",")
    known = cells(a.delay_list, a.method_list)
    for c in a.train_list or []:
        if c not in known:
            ap.error(f"--train: unknown condition {c!r}; the study's are {known}")
    return a


def main(argv: list[str] | None = None) -> int:
    """Parse the command line, then train, evaluate and write (or merge shards)."""
    a = _parse(argv)
    if a.merge:
        rc = merge(a)
    elif a.jobs > 1:
        rc = run_jobs(a, sys.argv[1:] if argv is None else list(argv), Path(__file__))
    else:
        rc = run(a)
    if rc == 0 and a.ages_control:
        add_to_study(Path(a.out), log=lambda s: print(s, flush=True))
    return rc


if __name__ == "__main__":
    raise SystemExit(main())
