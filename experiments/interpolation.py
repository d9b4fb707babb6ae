#!/usr/bin/env python
"""Paper study "interpolation": the replay memory's Table III in kind, plus the eq. (15) ablation.

Flights (closed loop, ideal alignment, 100 Hz truth: ``sigma_lab.studies.interpolation_flights``):

* ``fixedwing`` — our 6-DoF TALON-class fixed wing, formation route 400 m × 300 m
  (a 90° turn every ~15 s at 20 m/s), mean wind (3, 2, 0) m/s + moderate Dryden
  turbulence (w20 = 15.4 m/s);
* ``quadrotor`` — our 6-DoF F450/P450-class multirotor, route 200 m × 150 m at
  10 m/s (abrupt corners), same wind;
* ``jsbsim:c172x`` (fixed wing, route 1 km × 0.75 km at 50 m/s) and ``jsbsim:F450``
  (multirotor, 200 m × 150 m at 10 m/s) — JSBSim aircraft, still air (their wind is
  not wired to ours).

Each flies a leader and followers holding the V (the followers' roll/slot corrections
are the aggressive part). The dense truth is decimated to the log rate (swept: 1, 2,
5, 10, 25 Hz), with white sensor noise (position 0.05 m, velocity 0.1 m/s, attitude
0.01 rad per sample: EKF-fused-estimate levels; ``--noise clean`` removes it), and
interpolated back at every held-out 100 Hz instant. Error: 3-D position distance to
the noise-free truth; mean / max / RMSE over instants and aircraft, mean over seeds.

Methods: ``linear``, ``cubic``, ``pchip``, ``akima`` (SciPy) and ``hermite-dw`` (ours,
window rule ``both``, w = 1, ω = 1). Ablation at the headline rate (2 Hz) of the window
rule (``none`` = logged velocities as tangents, ``fixed``, ``velocity``, ``attitude``,
``both``, ``literal``) for w = 1, 2, 3.

Outputs (``--out``, default ``out/interpolation``): ``results.csv`` (tidy), ``summary.json``,
``trajectories.png`` (Fig. 10-like), ``error_vs_rate.png``, ``ablation.png``.
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from sigma_lab.studies.interpolation_study import (
    COLUMNS,
    DT,
    HEADLINE,
    KIND,
    NOISE,
    RATES,
    WINDOWS,
    aggregate,
    run,
)

import sigma_des
from sigma_des.replay import INTERP_METHODS, RULES, WindowRule, interpolate

PAPER = {  # Table III: mean / max / RMSE (m)
    "fixed-wing": {"linear": (3.311, 11.626, 4.092), "cubic": (2.187, 10.204, 2.796),
                   "pchip": (1.389, 6.711, 1.895), "akima": (0.609, 4.089, 0.993),
                   "hermite-dw": (0.256, 1.798, 0.433)},
    "multirotor": {"linear": (0.410, 1.598, 0.598), "cubic": (0.365, 1.117, 0.434),
                   "pchip": (0.333, 0.886, 0.389), "akima": (0.259, 1.023, 0.336),
                   "hermite-dw": (0.102, 0.354, 0.121)},
}
def parser() -> argparse.ArgumentParser:
    """The study's command line."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="seconds: 2 aircraft types, 20 s")
    p.add_argument("--seeds", type=int, default=None, help="seeds (default 3; quick 1)")
    p.add_argument("--out", default="out/interpolation", help="output folder")
    p.add_argument("--no-jsbsim", action="store_true", help="skip the JSBSim aircraft")
    return p


def plots(res: dict[str, Any], agg: dict[str, Any], out: Path) -> list[str]:
    """trajectories.png, error_vs_rate.png and ablation.png; their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    types = res["types"]
    fig, axes = plt.subplots(2, len(types), figsize=(5 * len(types), 8),
                             gridspec_kw={"height_ratios": [3, 2]}, squeeze=False)
    for j, ac in enumerate(types):
        ax, ex = axes[0, j], axes[1, j]
        f, log, idx = res["flights"][ac]
        node = 1  # a follower: its slot corrections are the liveliest part
        sp = np.linalg.norm(np.diff(f.vel[:, node], axis=0), axis=1)
        k = int(np.argmax(np.convolve(sp, np.ones(200), "same")))  # busiest 2 s
        lo, hi = max(idx[0], k - 400), min(idx[-1], k + 400)
        q = f.t[lo:hi]
        ax.plot(f.pos[lo:hi, node, 1], f.pos[lo:hi, node, 0], "k-", lw=2.5, alpha=0.35,
                label="truth (100 Hz)")
        for m, st in (("cubic", ":"), ("pchip", "--"), ("akima", "-."), ("hermite-dw", "-")):
            p = interpolate(log.t, log.pos[:, node], m, at=q, velocities=log.vel[:, node],
                            attitudes=log.att[:, node])
            ax.plot(p[:, 1], p[:, 0], st, lw=1.2, label=m)
            ex.plot(q, np.linalg.norm(p - f.pos[lo:hi, node], axis=1), st, lw=1.2, label=m)
        sel = (log.t >= q[0]) & (log.t <= q[-1])
        ax.plot(log.pos[sel, node, 1], log.pos[sel, node, 0], "o", color="red", ms=4,
                label=f"log ({HEADLINE:g} Hz, noisy)")
        ax.set_title(f"{ac} ({KIND[ac]}), node {node}")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=7)
        ex.set_xlabel("t (s)")
        ex.set_ylabel("3-D error (m)")
    fig.tight_layout()
    fig.savefig(out / "trajectories.png", dpi=120)
    plt.close(fig)
    names.append("trajectories.png")
    fig, axes = plt.subplots(1, len(types), figsize=(5 * len(types), 4), sharey=False)
    for ax, ac in zip(np.atleast_1d(axes), types, strict=True):
        for m in INTERP_METHODS:
            ys = [agg[ac]["noisy"][str(r)][m]["mean"] for r in RATES]
            ax.loglog(RATES, ys, "o-", label=m)
        ax.set_title(ac)
        ax.set_xlabel("log rate (Hz)")
        ax.set_ylabel("mean 3-D error (m)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "error_vs_rate.png", dpi=120)
    plt.close(fig)
    names.append("error_vs_rate.png")
    fig, ax = plt.subplots(figsize=(9, 4))
    labels = [f"{r}-w{w}" for w in WINDOWS for r in RULES if not (r == "none" and w > 1)]
    x = np.arange(len(labels))
    for j, ac in enumerate(types):
        ys = [agg[ac]["noisy"][str(HEADLINE)]["ablation:" + lab]["mean"] for lab in labels]
        ax.bar(x + j * 0.8 / len(types), ys, 0.8 / len(types), label=ac)
    ax.set_xticks(x + 0.4, labels, rotation=60, fontsize=7)
    ax.set_ylabel(f"mean 3-D error at {HEADLINE:g} Hz (m)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "ablation.png", dpi=120)
    plt.close(fig)
    names.append("ablation.png")
    return names


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = parser().parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res = run(args)
    agg = aggregate(res["rows"])
    with (out / "results.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(res["rows"])
    pngs = plots(res, agg, out)
    summary = {
        "study": "interpolation", "version": sigma_des.__version__,
        "command": shlex.join([sys.argv[0], *(argv if argv is not None else sys.argv[1:])]),
        "quick": args.quick, "seeds": res["seeds"], "aircraft": res["types"],
        "kind": {a: KIND[a] for a in res["types"]}, "nodes": res["n"],
        "duration_s": res["duration"], "truth_hz": 1 / DT, "rates_hz": list(RATES),
        "headline_hz": HEADLINE, "noise": {k: vars(v) for k, v in NOISE.items()},
        "window_default": vars(WindowRule()), "paper": PAPER, "results": agg,
        "plots": pngs, "wall_s": time.perf_counter() - t0,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    print(f"wrote {out / 'results.csv'}, {out / 'summary.json'} and {len(pngs)} plots "
          f"in {summary['wall_s']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
