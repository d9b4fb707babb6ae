"""Plots shared by the paper-study scripts: one colour per method, bars, AoI panels.

:func:`plot_setup` imports pyplot with the non-interactive Agg backend; :func:`save`
writes a figure as PNG (draft quality after ``plot_setup(fast=True)``, used by
``--quick`` runs).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.plots import rate_series
from sigma_des.studies.model import Study

__all__ = [
    "COLORS",
    "bar_metric",
    "bar_panels",
    "plot_aoi_dist",
    "plot_aoi_time",
    "plot_rate",
    "plot_setup",
    "save",
]

#: One colour per method label, the same in every plot.
COLORS: dict[str, str] = {
    "none": "#7f7f7f",
    "lockstep": "#d62728",
    "lockstep_evict": "#ff9896",
    "hlc": "#1f77b4",
    "bides": "#2ca02c",
}


_FAST_PLOTS = False  # set by plot_setup, read by save


def plot_setup(fast: bool = False) -> Any:
    """Import pyplot with the non-interactive Agg backend and a readable style.

    Args:
        fast: draft quality (lower resolution, no tight layout) — for ``--quick``
            runs, where drawing would otherwise take most of the run's time.
    """
    global _FAST_PLOTS
    _FAST_PLOTS = fast
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "figure.dpi": 110,
            "savefig.dpi": 110,
            "axes.grid": True,
            "grid.alpha": 0.3,
            "axes.titlesize": 11,
            "axes.labelsize": 10,
            "legend.fontsize": 8,
        }
    )
    return plt


def save(fig: Any, out: Path, name: str) -> Path:
    """Save ``fig`` as ``out/name`` (PNG) and close it."""
    path = Path(out) / name
    if _FAST_PLOTS:
        fig.savefig(path, dpi=50)
    else:
        fig.tight_layout()
        fig.savefig(path)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def bar_metric(
    ax: Any,
    study: Study,
    variant: str,
    metric: str,
    scale: float = 1.0,
    labels: Sequence[str] | None = None,
) -> None:
    """Bars of one metric per method label: mean over seeds, error bar = std over seeds."""
    labels = list(labels) if labels is not None else study.labels(variant)
    means, errs = [], []
    for lab in labels:
        xs = study.values(variant, lab, metric) * scale
        means.append(float(np.nanmean(xs)) if xs.size else math.nan)
        errs.append(float(np.nanstd(xs)) if xs.size > 1 else 0.0)
    x = np.arange(len(labels))
    ax.bar(x, means, yerr=errs, capsize=4, color=[COLORS.get(lab, "C0") for lab in labels])
    ax.set_xticks(x, labels)
    for xi, m in zip(x, means, strict=True):
        if math.isfinite(m):
            ax.annotate(
                f"{m:.3g}",
                (xi, m),
                ha="center",
                va="bottom",
                fontsize=8,
                xytext=(0, 2),
                textcoords="offset points",
            )


def plot_aoi_time(ax: Any, study: Study, variant: str, labels: Sequence[str] | None = None) -> None:
    """AoI over time (first seed): per-tick mean AoI as a line, per-tick max as a band."""
    labels = list(labels) if labels is not None else study.labels(variant)
    for lab in labels:
        r = study.runs(variant, lab)[0]
        ts = r.timeseries
        t = np.asarray(ts["t"], dtype=float)
        mean = np.asarray(ts["aoi_mean"], dtype=float) * 1000.0
        mx = np.asarray(ts["aoi_max"], dtype=float) * 1000.0
        c = COLORS.get(lab, None)
        ax.plot(t, mean, color=c, lw=1.0, label=f"{lab} (mean over nodes)")
        ax.fill_between(t, mean, mx, color=c, alpha=0.12, lw=0)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("AoI (ms)")
    ax.legend(loc="upper right", ncols=2)


def plot_aoi_dist(ax: Any, study: Study, variant: str, labels: Sequence[str] | None = None) -> None:
    """AoI distribution per method: violins of the per-render-tick mean AoI (all seeds).

    Markers show the engine's p50/p95/p99 over all (render tick × node) samples (mean
    over seeds), so both the swarm-average wobble and the per-node tail are visible.
    """
    labels = list(labels) if labels is not None else study.labels(variant)
    data = []
    for lab in labels:
        xs = np.concatenate(
            [np.asarray(r.timeseries["aoi_mean"], dtype=float) for r in study.runs(variant, lab)]
        )
        xs = xs[~np.isnan(xs)] * 1000.0
        data.append(xs if xs.size else np.array([np.nan]))
    pos = np.arange(1, len(labels) + 1)
    ok = [i for i, d in enumerate(data) if np.isfinite(d).any()]
    if ok:
        parts = ax.violinplot([data[i] for i in ok], positions=pos[ok], showmedians=True)
        for body, i in zip(parts["bodies"], ok, strict=True):
            body.set_facecolor(COLORS.get(labels[i], "C0"))
            body.set_alpha(0.5)
    for q, mk in (("p50", "o"), ("p95", "^"), ("p99", "v")):
        ys = [float(np.nanmean(study.values(variant, lab, f"aoi_{q}"))) for lab in labels]
        ax.scatter(pos + 0.25, ys, marker=mk, color="k", s=18, label=f"{q} of node samples")
    ax.set_xticks(pos, labels)
    ax.set_ylabel("AoI (ms)")
    ax.legend(loc="upper left")


def bar_panels(
    axs: Any, study: Study, variant: str, panels: Sequence[tuple[str, float, str]]
) -> None:
    """One :func:`bar_metric` panel per ``(metric, scale, ylabel)``, titled by the metric."""
    for ax, (metric, scale, ylabel) in zip(axs.flat, panels, strict=True):
        bar_metric(ax, study, variant, metric, scale)
        ax.set_ylabel(ylabel)
        ax.set_title(metric)


def plot_rate(
    ax: Any, study: Study, variant: str, key: str, window: float, lw: float = 1.0
) -> None:
    """Per label (first seed): the advance rate of series ``key`` in ``window``-s windows."""
    for lab in study.labels(variant):
        ts = study.runs(variant, lab)[0].timeseries
        t, rate = rate_series(ts["t"], ts[key], window=window)
        ax.plot(t, rate, color=COLORS.get(lab), lw=lw, label=lab)
