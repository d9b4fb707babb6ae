"""Control for the delay study: perfect-trained policies under delay with the ages hidden.

A policy trained with perfect information only ever sees ages of 0. Under delay its
age columns carry values it never saw. This script retrains the study's
perfect-information policies (same learner, budget and seeds: training is
deterministic) and evaluates each under every delay cell twice, on the study's
held-out episodes: with the ages shown (must equal the study's own figures) and with
the age columns set to 0 (``hidden``). It compares both with the delay-trained
policies of the study (paired over seeds, one-sided t test).

Outputs (``--out``): ``control.csv`` and ``summary.json``.

Usage: ``python experiments/train_ages_control.py --study out/env/delay_cem
[--out out/env/ages_control_cem]``
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats
from sigma_lab.studies.delay import cells, ci95, env_kwargs
from sigma_lab.studies.delay_study import train_one

from sigma_des import __version__
from sigma_des.env.learn import score

#: Age columns of the ``tight`` observation (own, leader, nearest neighbour).
AGE_COLUMNS = [5, 8, 13]


def main(argv: list[str] | None = None) -> int:
    """Retrain, evaluate shown and hidden, write the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True, help="a train_under_delay.py output directory")
    ap.add_argument("--out", default=None, help="default: <study>_ages_control")
    args = ap.parse_args(argv)
    study = json.loads((Path(args.study) / "summary.json").read_text())
    a = argparse.Namespace(**study["args"])
    seeds = study["seeds_done"]
    conds = cells([float(x) for x in a.delays.split(",")], a.methods.split(","))
    out = Path(args.out or f"{args.study.rstrip('/')}_ages_control")
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for seed in seeds:
        policy, _, _ = train_one(a, "perfect", seed, [])

        def hidden(obs: np.ndarray, p: Any = policy) -> np.ndarray:
            o = obs.copy()
            o[..., AGE_COLUMNS] = 0.0
            return p(o)

        for cell in conds[1:]:
            kw = env_kwargs(cell, a.nodes, a.max_steps, a.loss)
            for view, pol in (("shown", policy), ("hidden", hidden)):
                r = score(pol, kw, a.eval_episodes, a.eval_seed)
                rows.append({"seed": seed, "evaluated": cell, "ages": view,
                             "fitness": float(r["fitness"].mean())})
            print(f"seed {seed} {cell:12s} shown {rows[-2]['fitness']:.3f} hidden "
                  f"{rows[-1]['fitness']:.3f}", flush=True)
    fit = {(e["trained"], e["seed"], e["evaluated"]): e["fitness"] for e in study["eval"]}
    table = []
    for cell in conds[1:]:
        d = np.array([fit[(cell, s, cell)] for s in seeds])
        sh = np.array([r["fitness"] for r in rows if r["evaluated"] == cell
                       and r["ages"] == "shown"])
        hi = np.array([r["fitness"] for r in rows if r["evaluated"] == cell
                       and r["ages"] == "hidden"])
        study_p = np.array([fit[("perfect", s, cell)] for s in seeds])
        table.append({
            "cell": cell, "n_seeds": len(seeds), "reproduces_study": bool(
                np.array_equal(sh, study_p)),
            "perfect_shown_mean": float(sh.mean()), "perfect_shown_ci95": ci95(sh),
            "perfect_hidden_mean": float(hi.mean()), "perfect_hidden_ci95": ci95(hi),
            "delay_trained_mean": float(d.mean()),
            "diff_vs_hidden_mean": float((d - hi).mean()), "diff_vs_hidden_ci95": ci95(d - hi),
            "t_p_delay_beats_hidden": float(stats.ttest_rel(d, hi, alternative="greater").pvalue)})
    with (out / "control.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*table[0], "learner", "version"])
        w.writeheader()
        for t in table:
            w.writerow({**t, "learner": a.learner, "version": __version__})
    (out / "summary.json").write_text(json.dumps(
        {"version": __version__, "study": args.study, "args": study["args"], "seeds": seeds,
         "rows": rows, "table": table}, indent=2) + "\n")
    for t in table:
        print(f"{t['cell']:12s} delay-trained {t['delay_trained_mean']:.3f}  perfect shown "
              f"{t['perfect_shown_mean']:.3f}  hidden {t['perfect_hidden_mean']:.3f} ± "
              f"{t['perfect_hidden_ci95']:.3f}  p={t['t_p_delay_beats_hidden']:.3g}  "
              f"reproduces study: {t['reproduces_study']}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
