"""The node-count sweep: grid, key figures, Lock-Step's degradation point, table, plots.

``experiments/sweep_nodes.py`` is a front end to this module: :func:`build_sweep`
makes the :class:`~sigma_des.sweep.Sweep` of N ∈ :data:`FULL_NODES` (20 aircraft per
host, as in the paper) × methods × seeds; after it ran, :func:`key_figures` picks
the :data:`KEY_METRICS` of the aggregate rows, :func:`lockstep_degradation` finds
where Lock-Step falls behind BiDES, :func:`summary` is ``summary.json``,
:func:`figure_table` the printed table and :func:`plot_figures` the PNGs. See
``lab/record/SWEEPS.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.config import METHODS, NODES_PER_HOST, load
from sigma_des.errors import ConfigError
from sigma_des.plots import plot_lines
from sigma_des.plotstyle import MIN_DPI, legend_outside, line_kw
from sigma_des.sweep import RunReport, Sweep

__all__ = [
    "DEGRADE_FACTOR",
    "FULL_NODES",
    "Figures",
    "KEY_METRICS",
    "PLOTS",
    "QUICK_NODES",
    "build_sweep",
    "degrade_line",
    "estimate_text",
    "figure_table",
    "key_figures",
    "lockstep_degradation",
    "plot_figures",
    "summary",
]

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
#: Key figures reported per (N, method) in summary.json and the printed table.
KEY_METRICS: tuple[str, ...] = (
    "aoi_mean",
    "aoi_p99",
    "latency_state_mean",
    "snapshot_rate_hz",
    "trigger_rate_hz",
    "throughput_mbps",
)

#: ``{method: {N: {metric: {"mean", "ci95", "n"}}}}``
Figures = dict[str, dict[int, dict[str, dict[str, float]]]]


def build_sweep(
    nodes: str | None = None,
    quick: bool = False,
    duration: float | None = None,
    seeds: str | None = None,
    methods: str = ",".join(METHODS),
    sets: Sequence[str] = (),
    out: str | Path = "out/sweep_nodes",
    store: str | Path | None = None,
) -> Sweep:
    """The sweep of the script's options (defaults: the full sweep; ``quick``: the smoke one).

    Args:
        nodes: comma list of node counts (default :data:`FULL_NODES`, or
            :data:`QUICK_NODES` if ``quick``); ``hosts = ⌈N / NODES_PER_HOST⌉``.
        quick: 0.5 s simulated and 2 seeds unless given.
        duration: simulated seconds (default 10; the warm-up is 0.1 s up to 1 s
            simulated, else 1 s).
        seeds: ``N`` (seeds 1..N) or a comma list (default 5).
        methods: comma list of methods.
        sets: further ``key=value`` overrides.
        out: the output directory (the store defaults to ``out/sweep.sqlite``).
        store: the SQLite results store.

    Raises:
        ConfigError: a bad node list, override, method or seed list.
    """
    if nodes:
        try:
            counts = [int(x) for x in nodes.split(",") if x.strip()]
        except ValueError:
            raise ConfigError(
                "--nodes", f"must be a comma list of integers, got {nodes!r}"
            ) from None
    else:
        counts = list(QUICK_NODES if quick else FULL_NODES)
    dur = duration if duration is not None else (0.5 if quick else 10.0)
    warmup = 0.1 if dur <= 1.0 else 1.0
    seeds = seeds if seeds is not None else ("2" if quick else "5")
    base = load(None, [f"duration={dur}", f"warmup={warmup}", *sets])
    points = [{"nodes": n, "hosts": max(1, math.ceil(n / NODES_PER_HOST))} for n in counts]
    path = Path(store) if store else Path(out) / "sweep.sqlite"
    return Sweep(base, points, methods, seeds, path)


def estimate_text(sw: Sweep, workers: int, retry_failed: bool) -> str:
    """The line printed before the runs: how many, where stored, a rough time estimate."""
    est = sw.estimate(workers, retry_failed)
    est_txt = f"{est:.0f} s" if est < 120 else f"{est / 60:.0f} min"
    return (
        f"{len(sw.pending(retry_failed))} runs to do (store {sw.store.path}); rough estimate "
        f"{est_txt} on {workers} worker(s) — interrupt at will, rerun to resume"
    )


def key_figures(agg: list[dict[str, Any]]) -> Figures:
    """``{method: {N: {metric: {mean, ci95, n}}}}`` of :data:`KEY_METRICS` from aggregate rows."""
    out: Figures = {}
    for r in agg:
        if r["metric"] not in KEY_METRICS:
            continue
        cell = out.setdefault(r["method"], {}).setdefault(int(r["nodes"]), {})
        cell[r["metric"]] = {"mean": r["mean"], "ci95": r["ci95"], "n": r["n"]}
    return out


def lockstep_degradation(fig: Figures) -> int | None:
    """Smallest N where Lock-Step's mean AoI > DEGRADE_FACTOR × BiDES's (None: nowhere).

    An N where either mean is not finite is passed over.
    """
    ls, bd = fig.get("lockstep", {}), fig.get("bides", {})
    for n in sorted(set(ls) & set(bd)):
        a, b = ls[n]["aoi_mean"]["mean"], bd[n]["aoi_mean"]["mean"]
        if math.isfinite(a) and math.isfinite(b) and a > DEGRADE_FACTOR * b:
            return n
    return None


def degrade_line(fig: Figures, n_deg: int | None) -> str:
    """The printed verdict on Lock-Step ("" unless both Lock-Step and BiDES ran)."""
    if "lockstep" not in fig or "bides" not in fig:
        return ""
    where = f"N = {n_deg}" if n_deg is not None else "not within the grid"
    return f"lock-step degrades (AoI > {DEGRADE_FACTOR:g} × BiDES's): {where}"


def summary(sw: Sweep, rep: RunReport, fig: Figures, n_deg: int | None) -> dict[str, Any]:
    """``summary.json``: the plan, the failed runs, the key figures and the degradation."""
    return {
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


def figure_table(fig: Figures) -> str:
    """One line per (N, method): AoI mean ± CI, state latency, snapshot and trigger rates."""
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


def _plot_metric(fig: Figures, metric: str, ylabel: str, all_n: list[int]) -> Any:
    """One metric's figure: mean per method with a 95 % CI band, log-x."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    f, ax = plt.subplots(figsize=(7.6, 4.2), layout="constrained")
    series = {}
    for i, method in enumerate([m for m in METHODS if m in fig]):
        ns = sorted(n for n in fig[method] if metric in fig[method][n])
        mean = np.array([fig[method][n][metric]["mean"] for n in ns], dtype=float)
        ci = np.array([fig[method][n][metric]["ci95"] for n in ns], dtype=float)
        ci[~np.isfinite(ci)] = 0.0
        series[method] = (np.array(ns, dtype=float), mean)
        ax.fill_between(ns, mean - ci, mean + ci, color=line_kw(method, i)["color"], alpha=0.2,
                        linewidth=0)
    plot_lines(ax, series)
    ax.set_xscale("log")
    ax.set_xticks(all_n)
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("physics nodes N (log scale)")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{ylabel.split(' (')[0]} vs swarm size (mean ± 95 % CI over seeds)")
    ax.title.set_fontsize(10)
    ax.grid(True, which="both", alpha=0.3)
    legend_outside(ax, title="method")
    return f


def plot_figures(fig: Figures, out: Path) -> list[Path]:
    """One PNG per :data:`PLOTS` metric in ``out``; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths: list[Path] = []
    all_n = sorted({n for d in fig.values() for n in d})
    for metric, stem, ylabel in PLOTS:
        f = _plot_metric(fig, metric, ylabel, all_n)
        path = out / f"{stem}.png"
        f.savefig(path, dpi=max(MIN_DPI, 120))
        plt.close(f)
        paths.append(path)
    return paths
