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
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sigma_des.config import METHODS, NODES_PER_HOST, load
from sigma_des.errors import ConfigError
from sigma_des.studies import json_ready
from sigma_des.sweep import Sweep

#: Node counts of the full sweep and of ``--quick``.
FULL_NODES: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000)
QUICK_NODES: tuple[int, ...] = (10, 20)
#: Lock-Step "degrades" where its mean AoI exceeds BiDES's by more than this factor.
DEGRADE_FACTOR = 1.5

#: Plotted metrics: (metric, file stem, y-axis label).
PLOTS: tuple[tuple[str, str, str], ...] = (
    ("aoi_mean", "aoi_vs_nodes", "mean Age of Information (ms)"),
    ("latency_state_mean", "latency_vs_nodes", "mean state latency, publish → delivery (ms)"),
    ("snapshot_rate_hz", "snapshot_rate_vs_nodes", "new aligned snapshots per second (Hz)"),
)
#: Marker and line style per method (overlapping curves stay visible).
STYLES: dict[str, tuple[str, str]] = {
    "none": ("o", ":"),
    "lockstep": ("s", "--"),
    "hlc": ("^", "-."),
    "bides": ("D", "-"),
}
#: Key figures reported per (N, method) in summary.json and the printed table.
KEY_METRICS: tuple[str, ...] = (
    "aoi_mean",
    "aoi_p99",
    "latency_state_mean",
    "snapshot_rate_hz",
    "trigger_rate_hz",
    "throughput_mbps",
)


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


def build_sweep(a: argparse.Namespace) -> Sweep:
    """The sweep of the arguments (validated: raises ConfigError on bad input)."""
    if a.nodes:
        try:
            nodes = [int(x) for x in a.nodes.split(",") if x.strip()]
        except ValueError:
            raise ConfigError(
                "--nodes", f"must be a comma list of integers, got {a.nodes!r}"
            ) from None
    else:
        nodes = list(QUICK_NODES if a.quick else FULL_NODES)
    duration = a.duration if a.duration is not None else (0.5 if a.quick else 10.0)
    warmup = 0.1 if duration <= 1.0 else 1.0
    seeds = a.seeds if a.seeds is not None else ("2" if a.quick else "5")
    base = load(None, [f"duration={duration}", f"warmup={warmup}", *a.sets])
    points = [{"nodes": n, "hosts": max(1, math.ceil(n / NODES_PER_HOST))} for n in nodes]
    store = Path(a.store) if a.store else Path(a.out) / "sweep.sqlite"
    return Sweep(base, points, a.methods, seeds, store)


def key_figures(agg: list[dict[str, Any]]) -> dict[str, dict[int, dict[str, dict[str, float]]]]:
    """``{method: {N: {metric: {mean, ci95, n}}}}`` from aggregate rows."""
    out: dict[str, dict[int, dict[str, dict[str, float]]]] = {}
    for r in agg:
        if r["metric"] not in KEY_METRICS:
            continue
        cell = out.setdefault(r["method"], {}).setdefault(int(r["nodes"]), {})
        cell[r["metric"]] = {"mean": r["mean"], "ci95": r["ci95"], "n": r["n"]}
    return out


def lockstep_degradation(fig: dict[str, dict[int, dict[str, dict[str, float]]]]) -> int | None:
    """Smallest N where Lock-Step's mean AoI > DEGRADE_FACTOR × BiDES's (None: nowhere)."""
    ls, bd = fig.get("lockstep", {}), fig.get("bides", {})
    for n in sorted(set(ls) & set(bd)):
        a, b = ls[n]["aoi_mean"]["mean"], bd[n]["aoi_mean"]["mean"]
        if math.isfinite(a) and math.isfinite(b) and a > DEGRADE_FACTOR * b:
            return n
    return None


def plot(fig: dict[str, dict[int, dict[str, dict[str, float]]]], out: Path) -> list[Path]:
    """One PNG per plotted metric: mean per method with a 95 % CI band, log-x."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    paths: list[Path] = []
    all_n = sorted({n for d in fig.values() for n in d})
    for metric, stem, ylabel in PLOTS:
        f, ax = plt.subplots(figsize=(6.4, 4.2))
        for method in [m for m in METHODS if m in fig]:
            style = STYLES.get(method, ("o", "-"))
            ns = sorted(n for n in fig[method] if metric in fig[method][n])
            mean = [fig[method][n][metric]["mean"] for n in ns]
            ci = [fig[method][n][metric]["ci95"] for n in ns]
            ci = [0.0 if not math.isfinite(c) else c for c in ci]
            hollow = method == "lockstep"  # drawn larger and hollow: it often equals BiDES
            (line,) = ax.plot(
                ns,
                mean,
                marker=style[0],
                linestyle=style[1],
                markersize=10 if hollow else 6,
                markerfacecolor="none" if hollow else None,
                label=method,
            )
            lo = [m - c for m, c in zip(mean, ci, strict=True)]
            hi = [m + c for m, c in zip(mean, ci, strict=True)]
            ax.fill_between(ns, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
        ax.set_xscale("log")
        ax.set_xticks(all_n)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("physics nodes N (log scale)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{ylabel.split(' (')[0]} vs swarm size (mean ± 95 % CI over seeds)")
        ax.title.set_fontsize(10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(title="method")
        f.tight_layout()
        path = out / f"{stem}.png"
        f.savefig(path, dpi=120)
        plt.close(f)
        paths.append(path)
    return paths


def _table(fig: dict[str, dict[int, dict[str, dict[str, float]]]]) -> str:
    lines = [f"{'N':>6} {'method':>9} {'AoI ms':>16} {'lat ms':>8} {'snap Hz':>8} {'trig Hz':>8}"]
    ns = sorted({n for m in fig.values() for n in m})
    for n in ns:
        for method in [m for m in METHODS if m in fig and n in fig[m]]:
            c = fig[method][n]
            aoi = f"{c['aoi_mean']['mean']:.2f} ± {c['aoi_mean']['ci95']:.2f}"
            lines.append(
                f"{n:>6} {method:>9} {aoi:>16} {c['latency_state_mean']['mean']:>8.2f} "
                f"{c['snapshot_rate_hz']['mean']:>8.1f} {c['trigger_rate_hz']['mean']:>8.1f}"
            )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sweep, write tables, summary and plots; returns the exit status."""
    a = _args(argv)
    try:
        sw = build_sweep(a)
    except ConfigError as e:
        print(f"sweep_nodes: error: {e}", file=sys.stderr)
        return 2
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    workers = 1 if a.in_process else a.workers
    est = sw.estimate(workers, a.retry_failed)
    print(f"sweep_nodes: {sw.describe()}")
    est_txt = f"{est:.0f} s" if est < 120 else f"{est / 60:.0f} min"
    print(
        f"{len(sw.pending(a.retry_failed))} runs to do (store {sw.store.path}); rough estimate "
        f"{est_txt} on {workers} worker(s) — interrupt at will, rerun to resume",
        flush=True,
    )
    client = "inprocess" if a.in_process else a.scheduler
    try:
        rep = sw.run(client, a.workers, not a.no_progress, a.retry_failed)
    except KeyboardInterrupt:
        print("\ninterrupted: finished runs are stored; rerun to resume", file=sys.stderr)
        return 130
    print(rep.text())
    runs_csv, agg_csv = sw.write(out)
    agg = sw.aggregate(include_wall=False)
    fig = key_figures(agg)
    n_deg = lockstep_degradation(fig)
    pngs = plot(fig, out) if fig else []
    summary = {
        "nodes": [p["nodes"] for p in sw.points],
        "hosts": [p["hosts"] for p in sw.points],
        "methods": sw.methods,
        "seeds": sw.seeds,
        "duration_s": sw.base.duration,
        "warmup_s": sw.base.warmup,
        "runs": rep.total,
        "failed": [{"key": list(k), "error": e} for k, e in rep.failures],
        "lockstep_degrades_at": n_deg,
        "degrade_rule": f"lockstep aoi_mean > {DEGRADE_FACTOR} x bides aoi_mean",
        "figures": {m: {str(n): v for n, v in d.items()} for m, d in fig.items()},
    }
    (out / "summary.json").write_text(
        json.dumps(json_ready(summary), indent=2, sort_keys=True, allow_nan=False) + "\n"
    )
    print(_table(fig))
    if "lockstep" in fig and "bides" in fig:
        where = f"N = {n_deg}" if n_deg is not None else "not within the grid"
        print(f"lock-step degrades (AoI > {DEGRADE_FACTOR:g} × BiDES's): {where}")
    print(f"wrote {runs_csv}, {agg_csv}, {out / 'summary.json'}, " + ", ".join(map(str, pngs)))
    return 1 if rep.failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
