#!/usr/bin/env python
"""Paper study "formation": five fixed-wing aircraft in a leader–follower V.

The paper's figures: docs/concepts/paper.md.

The swarm: 5 fixed-wing aircraft (``dynamics = "fixedwing"``, the TALON-class
preset, trimmed at 20 m/s and 100 m; ``--dynamics-params minisgs`` flies the fixed
wing fitted to JSBSim's minisgs glider instead, with the preset's propeller),
behaviour ``formation`` — the leader (node 0) flies the clockwise 1 km × 0.75 km
rectangle, the followers hold V slots with the paper's law (eqs. 16–19) and a
separation rule. The paper's parameters d = 30 m, θ = 45°, P_φ = 0.015,
P_ψ = 0.4, P_v = 0.3, v_cru = 20 m/s are the defaults of ``formation_rule`` /
``formation_behaviour``; the script checks that at start-up and records them in
``summary.json``. Trajectories are logged at 30 Hz
of physics time (``fidelity.log_rate``).

Runs, per seed: every alignment method (none, lockstep, hlc, bides) over the
chosen network (one aircraft per host), plus the *ideal* run (zero latency,
perfect alignment: :func:`sigma_des.agents.ideal.fly`, the reference of
``sigma_des.api.ideal_run``). Networks (``--network``):

* ``lossy`` (default) — the latency-tolerance study's network
  (``scenarios/latency_tolerance.toml``): 30 ± 10 ms one-way delay and 30 %
  packet loss on every physics host's link, datagram transport, QoS 0, alignment
  and rendering at 30 Hz, physics at 100 Hz — so the methods differ;
* ``default`` — the default scenario's LAN (0.25 ms links, TCP-like, QoS 1);
* ``ideal`` — the default scenario with zero link latency and no loss.

Start (``--start``): ``offset`` (default) puts every follower ``--offset H,V``
metres off its slot (horizontally along and across track, vertically alternating
up/down, on alternating sides); ``grid`` is the model's own start (30 m grid, all
at 100 m, heading north), from which the rear followers need ~40 s to reach their
slots.

Metrics (per method and for the ideal run): see :mod:`sigma_lab.studies.formation_flight`
(convergence to the V slots, distance to slot, formation error and DTW against the
ideal run, flight covered, and the engine's own metrics of each run).

Outputs (``--out``, default ``out/formation``): ``results.csv`` (tidy: one row per
seed × method × metric with ``config_hash`` and ``version``), ``summary.json``
(command, parameters, per method mean / std / per-seed values), and PNGs:
``trajectories.png`` (north vs east per method and ideal), ``convergence.png``
(horizontal and vertical distance to slot vs time), ``formation_error.png``
(formation error over time and DTW per method).

Examples::

    python experiments/formation.py                 # 150 s flights, seeds 1,2,3, lossy net
    python experiments/formation.py --quick --out /tmp/formation
    python experiments/formation.py --network default --seeds 1 --duration 120
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from sigma_lab import studies
from sigma_lab.studies.formation_flight import (
    IDEAL,
    LEADER,
    METHODS,
    N_AIRCRAFT,
    check_paper_parameters,
    run_seed,
    write_outputs,
)

from sigma_des import load
from sigma_des.config import Scenario

NAME = "formation"
SCENARIO_LOSSY = Path(__file__).resolve().parent.parent / "scenarios" / "latency_tolerance.toml"
COMMON = (f"nodes={N_AIRCRAFT}", f"hosts={N_AIRCRAFT}", "dynamics=fixedwing",
          'commands.behaviour="formation"', "fidelity.log_rate=30.0", "f_trig=100.0")
NETWORKS: dict[str, tuple[Path | None, tuple[str, ...]]] = {
    "lossy": (SCENARIO_LOSSY, ()),
    "default": (None, ()),
    "ideal": (None, ('net.host_link.latency={dist="constant", value=0.0}',
                     'net.server_link.latency={dist="constant", value=0.0}')),
}


def scenario(network: str, duration: float, seed: int, params: str = "") -> Scenario:
    """The scenario of one network, flight duration and seed (``params``: a fitted file)."""
    path, extra = NETWORKS[network]
    warm = min(1.0, 0.2 * duration)
    fit = [f"dynamics_params={json.dumps(params)}"] if params else []
    return load(path, [*studies.known(COMMON), *extra, *fit, f"duration={duration}",
                       f"warmup={warm}", f"seed={seed}"])


def plots(args: argparse.Namespace, r: dict[str, Any]) -> None:
    """trajectories.png, convergence.png, formation_error.png (first seed)."""
    plt = studies.plot_setup(args.quick)
    out = Path(args.out)
    labels = [IDEAL, *METHODS]
    seed = r["seed"]

    fig, axs = plt.subplots(1, len(labels), figsize=(3.6 * len(labels), 4.2), sharex=True,
                            sharey=True)
    for ax, lab in zip(axs, labels, strict=True):
        pos = r["traj"][lab]
        for k in range(pos.shape[1]):
            ax.plot(pos[:, k, 1], pos[:, k, 0], lw=1.4 if k == LEADER else 0.8,
                    color="k" if k == LEADER else f"C{k}",
                    label="leader" if k == LEADER else f"follower {k}")
            ax.plot(pos[-1, k, 1], pos[-1, k, 0], "o", ms=3, color="k" if k == LEADER else f"C{k}")
        ax.set_title(f"{lab} ({r['metrics'][lab]['flight_s']:.0f} s flight)")
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal", adjustable="box")
    axs[0].set_ylabel("north (m)")
    studies.legend_outside(axs[-1], fontsize=7)
    fig.suptitle(f"Trajectories, {args.network} network, seed {seed} (dot = end)")
    studies.save(fig, out, "trajectories.png")

    fig, axs = plt.subplots(2, len(labels), figsize=(3.6 * len(labels), 6.2), sharex=True,
                            sharey="row")
    for col, lab in enumerate(labels):
        ser = r["series"][lab]
        for row, key, thr, name in ((0, "dh", args.h_threshold, "horizontal"),
                                    (1, "dv", args.v_threshold, "vertical")):
            ax = axs[row, col]
            for k in range(ser[key].shape[1]):
                if k == LEADER:
                    continue
                ax.plot(ser["t"], ser[key][:, k], lw=0.8, color=f"C{k}", label=f"follower {k}")
            ax.axhline(thr, color="k", ls="--", lw=0.8, label=f"threshold {thr:g} m")
            ax.axvline(float(ser["t_end"]), color="grey", ls=":", lw=0.8,
                       label="window end (1st turn)")
            ax.set_ylim(bottom=0.0)
            if col == 0:
                ax.set_ylabel(f"{name} distance to slot (m)")
            if row == 0:
                ax.set_title(lab)
            else:
                ax.set_xlabel("flight time (s)")
    studies.legend_outside(axs[0, -1], fontsize=7)
    fig.suptitle(f"Convergence to the V slots, {args.network} network, seed {seed}")
    studies.save(fig, out, "convergence.png")

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.2))
    err = {}
    for lab in METHODS:
        ser = r["series"][lab]
        n = len(ser["formation_err"])
        err[lab] = (ser["t"][:n], ser["formation_err"])
    studies.plot_lines(axs[0], err, lw=1.0)
    axs[0].set_xlabel("flight time (s)")
    axs[0].set_ylabel("formation (shape) error vs ideal (m)")
    axs[0].set_title("Formation error over time")
    dist = {}
    for lab in labels:
        ser = r["series"][lab]
        foll = [k for k in range(ser["dh"].shape[1]) if k != LEADER]
        dist[lab] = (ser["t"], ser["dh"][:, foll].mean(axis=1))
    studies.plot_lines(axs[1], dist, lw=1.0)
    axs[1].set_yscale("log")
    axs[1].set_xlabel("flight time (s)")
    axs[1].set_ylabel("mean horizontal distance to slot (m)")
    axs[1].set_title("Followers' mean distance to slot")
    studies.legend_outside(axs[1])
    x = np.arange(len(labels))
    ys = [r["metrics"][lab]["dtw_r"] for lab in labels]
    axs[2].bar(x, ys, color=[studies.line_kw(lab)["color"] for lab in labels])
    axs[2].set_xticks(x, labels)
    axs[2].set_ylabel("normalised DTW to ideal, r = D·T/s (m)")
    axs[2].set_title("Trajectory DTW to the ideal run (mean over nodes)")
    for xi, y in zip(x, ys, strict=True):
        axs[2].annotate(f"{y:.3g}", (xi, y), ha="center", va="bottom", fontsize=8)
    studies.save(fig, out, "formation_error.png")


# ------------------------------------------------------------------ main


def parser() -> argparse.ArgumentParser:
    """The study's command line (the common one plus the formation options)."""
    p = studies.study_parser(NAME, __doc__, default_seeds="1,2,3")
    p.add_argument("--network", choices=tuple(NETWORKS), default="lossy",
                   help="network between hosts and broker (default: lossy)")
    p.add_argument("--duration", type=float, default=None,
                   help="flight time, s (default 150; --quick: 6)")
    p.add_argument("--dynamics-params", dest="dynamics_params", default="", metavar="TOML",
                   help="fitted fixed-wing parameters (a sigma-des tune file or a shipped "
                   "fit, e.g. minisgs: the fixed wing fitted to JSBSim's glider)")
    p.add_argument("--start", choices=("offset", "grid"), default="offset",
                   help="initial positions (default: followers offset from their slots)")
    p.add_argument("--offset", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=None, help="start offset from the slot 'H,V' in m "
                   "(default 20,8; --quick: 6,3)")
    p.add_argument("--h-threshold", type=float, default=5.0, help="horizontal threshold, m")
    p.add_argument("--v-threshold", type=float, default=2.0, help="vertical threshold, m")
    p.add_argument("--match-flight", dest="match_flight", action="store_true", default=None,
                   help="re-run a method that covered less flight with a longer simulated "
                   "duration (default in full mode)")
    p.add_argument("--no-match-flight", dest="match_flight", action="store_false")
    p.add_argument("--max-stretch", type=float, default=40.0,
                   help="--match-flight: longest simulated duration, in flight durations")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.finish_args(parser().parse_args(argv))
    if args.duration is None:
        args.duration = 6.0 if args.quick else 150.0
    if args.offset is None:
        args.offset = (6.0, 3.0) if args.quick else (20.0, 8.0)
    if len(args.offset) != 2:
        raise SystemExit("--offset takes two numbers, H,V")
    if args.match_flight is None:
        args.match_flight = not args.quick
    params = check_paper_parameters()
    t0 = time.perf_counter()
    runs = [run_seed(args, scenario(args.network, args.duration, s, args.dynamics_params))
            for s in args.seeds]
    wall = time.perf_counter() - t0
    write_outputs(args, runs, params, wall)
    plots(args, runs[0])
    studies.update_plot_list(Path(args.out))
    print(json.loads((Path(args.out) / "summary.json").read_text())["table"])
    print(f"wrote {args.out} ({wall:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
