"""Plots shared by the paper-study scripts: bars, AoI panels, rates — in the house style.

Every method is drawn in its :mod:`sigma_des.plotstyle` colour, line style and marker,
the same as in ``compare``'s plots (:data:`COLORS` *is* :data:`sigma_des.plotstyle.COLORS`).
:func:`plot_setup` imports pyplot with the non-interactive Agg backend and constrained
layout (titles and outside legends never overlap); :func:`save` writes a figure as PNG
(at :data:`~sigma_des.plotstyle.MIN_DPI` after ``plot_setup(fast=True)``, used by
``--quick`` runs, else at 110 dpi).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.plots import aoi_violins, moving_average, plot_lines, rate_series
from sigma_des.plotstyle import (
    COLORS,
    MIN_DPI,
    legend_outside,
    line_kw,
    metric_title,
    rate_ylim,
)
from sigma_lab.studies.model import Study

__all__ = [
    "COLORS",
    "bar_metric",
    "bar_panels",
    "legend_outside",
    "line_kw",
    "moving_average",
    "plot_aoi_dist",
    "plot_aoi_time",
    "plot_lines",
    "plot_rate",
    "plot_setup",
    "rate_ylim",
    "save",
]

_FAST_PLOTS = False  # set by plot_setup, read by save


def plot_setup(fast: bool = False) -> Any:
    """Import pyplot with the non-interactive Agg backend and a readable style.

    Args:
        fast: draft quality (:data:`~sigma_des.plotstyle.MIN_DPI`, still legible) —
            for ``--quick`` runs, where drawing would otherwise take much of the run's
            time.
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
            "figure.constrained_layout.use": True,
        }
    )
    return plt


def save(fig: Any, out: Path, name: str) -> Path:
    """Save ``fig`` as ``out/name`` (PNG) and close it."""
    path = Path(out) / name
    fig.savefig(path, dpi=MIN_DPI if _FAST_PLOTS else 110)
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
    ax.bar(x, means, yerr=errs, capsize=4,
           color=[line_kw(lab, i)["color"] for i, lab in enumerate(labels)])
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
    series = {}
    for i, lab in enumerate(labels):
        ts = study.runs(variant, lab)[0].timeseries
        t = np.asarray(ts["t"], dtype=float)
        series[lab] = (t, np.asarray(ts["aoi_mean"], dtype=float) * 1000.0)
        mx = np.asarray(ts["aoi_max"], dtype=float) * 1000.0
        ax.fill_between(t, series[lab][1], mx, color=line_kw(lab, i)["color"], alpha=0.12, lw=0)
    plot_lines(ax, series, " (mean over nodes)", lw=1.0)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("AoI (ms)")
    legend_outside(ax)


def plot_aoi_dist(ax: Any, study: Study, variant: str, labels: Sequence[str] | None = None) -> None:
    """AoI distribution per method: violins of the per-render-tick mean AoI (all seeds).

    Markers show the engine's p50/p95/p99 over all (render tick × node) samples (mean
    over seeds), so both the swarm-average wobble and the per-node tail are visible.
    """
    labels = list(labels) if labels is not None else study.labels(variant)
    data = {
        lab: np.concatenate(
            [np.asarray(r.timeseries["aoi_mean"], dtype=float) for r in study.runs(variant, lab)]
        )
        * 1000.0
        for lab in labels
    }
    tails = {
        q: [float(np.nanmean(study.values(variant, lab, f"aoi_{q}"))) for lab in labels]
        for q in ("p50", "p95", "p99")
    }
    aoi_violins(ax, data, tails)


def bar_panels(
    axs: Any, study: Study, variant: str, panels: Sequence[tuple[str, float, str]]
) -> None:
    """One :func:`bar_metric` panel per ``(metric, scale, ylabel)``, titled by the metric's
    human name (:func:`~sigma_des.plotstyle.metric_title`)."""
    for ax, (metric, scale, ylabel) in zip(axs.flat, panels, strict=True):
        bar_metric(ax, study, variant, metric, scale)
        ax.set_ylabel(ylabel)
        ax.set_title(metric_title(metric))


def plot_rate(
    ax: Any, study: Study, variant: str, key: str, window: float, lw: float = 1.0
) -> None:
    """Per label (first seed): the advance rate of series ``key`` in ``window``-s windows
    (labels whose rates coincide are named so in the legend)."""
    series = {}
    for lab in study.labels(variant):
        ts = study.runs(variant, lab)[0].timeseries
        series[lab] = rate_series(ts["t"], ts[key], window=window)
    plot_lines(ax, series, lw=lw)
