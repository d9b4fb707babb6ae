#!/usr/bin/env python
"""Node-count sweep: AoI, state latency and snapshot rate vs N for every method.

Runs N ∈ {10, 20, 50, 100, 200, 500, 1000} × all methods × 5 seeds (10 s simulated
each, 20 aircraft per host as in the paper) through :class:`sigma_des.sweep.Sweep` on
Dask (a LocalCluster on 127.0.0.1 by default, or ``--scheduler ADDR``). Every run is
stored in ``OUT/sweep.sqlite`` as it finishes, so an interrupted sweep resumes where
it stopped when the same command is run again.

Writes into ``--out`` (default ``out/sweep_nodes``):

* ``runs.csv`` — tidy per-run rows (nodes, hosts, config_hash, seed, method, metric,
  value, unit); ``aggregate.csv`` — mean, std, n, 95 % CI half-width over seeds;
* ``summary.json`` — the plan, the per-(N, method) key figures and where Lock-Step
  degrades;
* ``aoi_vs_nodes.png``, ``latency_vs_nodes.png``, ``snapshot_rate_vs_nodes.png`` —
  mean ± 95 % CI band per method, log-x.

It prints where Lock-Step degrades: the smallest N at which its mean AoI exceeds
BiDES's by more than 50 % (or "not within the grid").

Examples::

    python experiments/sweep_nodes.py                  # full: ~1 h on 2 cores (estimate printed)
    python experiments/sweep_nodes.py --quick          # N = 10, 20; 2 seeds; 0.5 s (smoke test)
    python experiments/sweep_nodes.py --scheduler tcp://10.0.0.5:8786 --seeds 10
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from sigma_lab.studies import json_ready
from sigma_lab.studies.node_sweep import (
    build_sweep,
    degrade_line,
    estimate_text,
    figure_table,
    key_figures,
    lockstep_degradation,
    plot_figures,
    summary,
)

from sigma_des.config import METHODS
from sigma_des.errors import ConfigError


def _args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="N = 10, 20; 2 seeds; 0.5 s each")
    p.add_argument("--nodes", default=None, help="comma list of node counts (overrides)")
    p.add_argument("--seeds", default=None, help="N (= 1..N) or a comma list (default 5; quick 2)")
    p.add_argument("--duration", type=float, default=None, help="simulated s (10; quick 0.5)")
    p.add_argument("--methods", default=",".join(METHODS), help="comma list of methods")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--out", default="out/sweep_nodes", metavar="DIR")
    p.add_argument("--store", default=None, metavar="FILE", help="default: OUT/sweep.sqlite")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster workers (default 2)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="ADDR", help="Dask scheduler address")
    where.add_argument("--in-process", action="store_true", help="no Dask; run here")
    p.add_argument("--retry-failed", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sweep, write tables, summary and plots; returns the exit status."""
    a = _args(argv)
    try:
        sw = build_sweep(a.nodes, a.quick, a.duration, a.seeds, a.methods, a.sets, a.out, a.store)
    except ConfigError as e:
        print(f"sweep_nodes: error: {e}", file=sys.stderr)
        return 2
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"sweep_nodes: {sw.describe()}")
    print(estimate_text(sw, 1 if a.in_process else a.workers, a.retry_failed), flush=True)
    client = "inprocess" if a.in_process else a.scheduler
    try:
        rep = sw.run(client, a.workers, not a.no_progress, a.retry_failed)
    except KeyboardInterrupt:
        print("\ninterrupted: finished runs are stored; rerun to resume", file=sys.stderr)
        return 130
    print(rep.text())
    runs_csv, agg_csv = sw.write(out)
    fig = key_figures(sw.aggregate(include_wall=False))
    n_deg = lockstep_degradation(fig)
    pngs = plot_figures(fig, out) if fig else []
    (out / "summary.json").write_text(
        json.dumps(json_ready(summary(sw, rep, fig, n_deg)), indent=2, sort_keys=True,
                   allow_nan=False) + "\n"
    )
    print(figure_table(fig))
    if line := degrade_line(fig, n_deg):
        print(line)
    print(f"wrote {runs_csv}, {agg_csv}, {out / 'summary.json'}, " + ", ".join(map(str, pngs)))
    return 1 if rep.failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
