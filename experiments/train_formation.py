"""Train the formation task under delay vs with perfect information; evaluate both under delay.

Two training conditions, the same CEM learner (``sigma_des.env.learn``) and seeds:

* ``delay``: BiDES alignment over lossy, slow host links (default latency normal
  150 ms ± 30 ms, Bernoulli loss 10 %; ``--latency``, ``--loss``), agents observe the
  aligned view;
* ``perfect``: what peer environments give — agents observe the true current
  state, on an ideal network (the scenario's default 0.25 ms links, no loss).

Each trained policy (and the untrained zero policy) is then evaluated on the same
held-out episodes under *both* conditions. Outputs (``--out``): ``history.csv``
(learning curves), ``eval.csv`` (evaluation table), ``summary.json`` and
``learning_curves.png``.

Usage: ``python experiments/train_formation.py [--quick] [--out /work/out/env/train]``
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from sigma_lab.studies import legend_outside, plot_setup, save

from sigma_des import __version__
from sigma_des.env.learn import CEMConfig, evaluate, train

DELAY = {"net.host_link.latency": {"dist": "normal", "mean": 0.15, "std": 0.03},
         "net.host_link.loss": {"p": 0.1}}
CONDITIONS: dict[str, dict[str, Any]] = {
    "delay": {"method": "bides", "overrides": DELAY, "perfect_info": False},
    "perfect": {"method": "none", "overrides": {}, "perfect_info": True},
}


def env_kwargs(cond: str, nodes: int, max_steps: int, latency: float = 0.15,
               loss: float = 0.1) -> dict[str, Any]:
    """SwarmVec arguments of one condition (``latency``, ``loss``: the delay condition's)."""
    c = CONDITIONS[cond]
    over = dict(c["overrides"])
    if over:
        over["net.host_link.latency"] = {"dist": "normal", "mean": latency,
                                         "std": latency / 5}
        over["net.host_link.loss"] = {"p": loss}
    return {"task": "formation", "method": c["method"], "max_steps": max_steps,
            "perfect_info": c["perfect_info"], "scenario": {"nodes": nodes, **over}}


def main(argv: list[str] | None = None) -> int:
    """Train under each condition, evaluate every policy under each, write the outputs."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny scale (seconds)")
    ap.add_argument("--nodes", type=int, default=5)
    ap.add_argument("--iterations", type=int, default=25)
    ap.add_argument("--population", type=int, default=16)
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--max-steps", type=int, default=100)
    ap.add_argument("--eval-episodes", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--latency", type=float, default=0.15,
                    help="delay condition: mean host-link latency (s), std = mean / 5")
    ap.add_argument("--loss", type=float, default=0.1, help="delay condition: loss probability")
    ap.add_argument("--out", default="out/env/train")
    a = ap.parse_args(argv)
    if a.quick:
        a.nodes, a.iterations, a.population, a.episodes = 3, 3, 6, 1
        a.max_steps, a.eval_episodes = 20, 2
    cfg = CEMConfig(population=a.population, elite=max(1, a.population // 4),
                    iterations=a.iterations, episodes=a.episodes, seed=a.seed)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    history: list[dict[str, Any]] = []
    policies: dict[str, np.ndarray] = {}
    wall: dict[str, float] = {}
    for cond in CONDITIONS:
        t0 = time.perf_counter()

        def log(row: dict[str, float], cond: str = cond) -> None:
            history.append({"trained": cond, **row})
            print(f"{cond:8s} it {int(row['iteration']):3d}: mean {row['mean_fitness']:8.3f} "
                  f"elite {row['elite_fitness']:8.3f} best err {row['best_error']:6.2f} m",
                  flush=True)

        kw = env_kwargs(cond, a.nodes, a.max_steps, a.latency, a.loss)
        policies[cond], _ = train(kw, cfg, log)
        wall[cond] = time.perf_counter() - t0
    shape = policies["delay"].shape
    policies["untrained"] = np.zeros(shape)
    evals = []
    eval_seed = 10_000 + a.seed  # held-out episodes, the same for every policy
    for trained, theta in policies.items():
        for cond in CONDITIONS:
            r = evaluate(theta, env_kwargs(cond, a.nodes, a.max_steps, a.latency, a.loss),
                         a.eval_episodes, eval_seed)
            evals.append({"trained": trained, "evaluated": cond, **r})
            print(f"trained {trained:9s} evaluated {cond:8s}: fitness {r['fitness']:8.3f} "
                  f"slot error {r['error']:6.2f} m failed {r['failed']:.2f}", flush=True)
    _write(out, a, history, evals, policies, wall)
    return 0


def _write(out: Path, a: argparse.Namespace, history: list[dict[str, Any]],
           evals: list[dict[str, Any]], policies: dict[str, np.ndarray],
           wall: dict[str, float]) -> None:
    for name, rows in (("history.csv", history), ("eval.csv", evals)):
        with (out / name).open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=[*rows[0], "seed", "version"])
            w.writeheader()
            for r in rows:
                w.writerow({**r, "seed": a.seed, "version": __version__})
    (out / "summary.json").write_text(json.dumps({
        "version": __version__, "args": vars(a), "conditions": CONDITIONS,
        "history": history, "eval": evals, "wall_s": wall,
        "policies": {k: v.tolist() for k, v in policies.items()}}, indent=2) + "\n")
    plt = plot_setup(fast=a.quick)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for cond, color in (("delay", "#d62728"), ("perfect", "#1f77b4")):
        rows = [r for r in history if r["trained"] == cond]
        it = [r["iteration"] for r in rows]
        ax.plot(it, [r["elite_fitness"] for r in rows], color=color, label=f"{cond}: elite")
        ax.plot(it, [r["mean_fitness"] for r in rows], color=color, ls="--", alpha=0.6,
                label=f"{cond}: population")
    ax.set_xlabel("CEM iteration")
    ax.set_ylabel("mean reward per agent-step")
    ax.set_title("formation task: learning curves (in each training condition)")
    legend_outside(ax)
    save(fig, out, "learning_curves.png")


if __name__ == "__main__":
    raise SystemExit(main())
