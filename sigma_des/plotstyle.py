"""The one look of every sigma_des plot: method palette, line styles, legends, rate axes.

``compare`` (:mod:`sigma_des.plots`), the paper studies (the lab)
and the ``experiments/`` scripts draw a method with the same colour, line style and
marker everywhere, so a reader who learnt "BiDES is the green solid line" in one
figure can trust it in the next. The palette is the Okabe–Ito set (readable with the
common colour-vision deficiencies); line styles and markers differ per method as well,
so two methods whose curves coincide stay visible, and :func:`coinciding` finds such
pairs so the legend can say "lockstep (= bides)".

This module needs no matplotlib: it only holds data and small pure helpers (the
drawing modules import pyplot themselves).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "COLORS",
    "METRIC_TITLES",
    "MIN_DPI",
    "STYLES",
    "MethodStyle",
    "coinciding",
    "legend_outside",
    "line_kw",
    "method_label",
    "metric_title",
    "rate_ylim",
    "spread_shares",
]


@dataclass(frozen=True)
class MethodStyle:
    """How one method is drawn: colour, line style, marker."""

    color: str
    ls: Any
    marker: str


#: One style per method label (also the peer method and the formation study's ideal
#: run). Other labels take a style of :data:`_OTHERS` by their line's index.
STYLES: Mapping[str, MethodStyle] = {
    "none": MethodStyle("#7f7f7f", "-", "o"),
    "lockstep": MethodStyle("#D55E00", "--", "s"),
    "lockstep_evict": MethodStyle("#E69F00", (0, (5, 2, 1, 2)), "x"),
    "hlc": MethodStyle("#0072B2", "-.", "^"),
    "bides": MethodStyle("#009E73", "-", "D"),
    "rpc": MethodStyle("#CC79A7", ":", "v"),
    "ideal": MethodStyle("#000000", (0, (1, 1)), "*"),
}
#: Styles of labels that are not methods (e.g. ``bides_mqtt``), by the line's index.
_OTHERS = (
    MethodStyle("#56B4E9", "-", "P"),
    MethodStyle("#882255", "--", "X"),
    MethodStyle("#44AA99", "-.", "h"),
    MethodStyle("#332288", ":", "p"),
    MethodStyle("#999933", "-", "d"),
    MethodStyle("#AA4499", "--", "<"),
)

#: One colour per method label, the same in every plot (the colours of :data:`STYLES`).
COLORS: Mapping[str, str] = {m: s.color for m, s in STYLES.items()}

#: Lowest resolution any plot of the project is saved with (``--quick`` included).
MIN_DPI = 100

#: Human titles for the metric keys that plots show as panels.
METRIC_TITLES: Mapping[str, str] = {
    "aoi_mean": "AoI, mean",
    "aoi_p99": "AoI, 99th percentile",
    "aoi_std": "AoI, standard deviation",
    "latency_state_mean": "State latency, mean",
    "latency_state_p99": "State latency, 99th percentile",
    "buffer_bytes_peak": "Alignment buffer, peak",
    "throughput_mbps": "Wire throughput",
    "snapshot_rate_hz": "Aligned snapshot rate",
    "trigger_rate_hz": "Achieved trigger rate",
    "f_trig_settled_hz": "Trigger rate in force (last quarter)",
    "broker_util": "Broker utilisation",
    "spread_mean": "Frame spread, mean",
    "formation_err_mean": "Formation error, mean",
    "dtw_r": "Trajectory DTW ratio",
    "rollbacks": "Rollbacks",
}


def _style(method: str, index: int = 0) -> MethodStyle:
    return STYLES.get(method, _OTHERS[index % len(_OTHERS)])


def metric_title(metric: str) -> str:
    """A plot title for ``metric``: its :data:`METRIC_TITLES` entry, else the key made
    readable (underscores to spaces, first letter capital)."""
    if metric in METRIC_TITLES:
        return METRIC_TITLES[metric]
    text = metric.replace("_", " ").strip()
    return text[:1].upper() + text[1:]


def coinciding(
    series: Mapping[str, ArrayLike], rtol: float = 1e-6, atol: float = 1e-9
) -> dict[str, str]:
    """Which methods draw the same curve as a method before them.

    Args:
        series: method -> the values it plots (same length to coincide; NaN equals NaN).
        rtol: relative tolerance of "the same".
        atol: absolute tolerance of "the same".

    Returns:
        ``{method: earlier method it coincides with}``; a method that coincides with
        several earlier ones maps to the first of them, one that coincides with none is
        absent.
    """
    firsts: list[tuple[str, NDArray[np.float64]]] = []
    twins: dict[str, str] = {}
    for m, ys in series.items():
        y = np.asarray(ys, dtype=float)
        for first, f in firsts:
            if f.shape == y.shape and np.allclose(f, y, rtol=rtol, atol=atol, equal_nan=True):
                twins[m] = first
                break
        else:
            firsts.append((m, y))
    return twins


def method_label(method: str, twins: Mapping[str, str], suffix: str = "") -> str:
    """The legend entry of ``method``: ``"lockstep (= bides)"`` when it coincides."""
    twin = f" (= {twins[method]})" if method in twins else ""
    return f"{method}{suffix}{twin}"


def line_kw(method: str, index: int = 0, n_points: int = 0, lw: float = 1.3) -> dict[str, Any]:
    """Keyword arguments of ``ax.plot`` for one method's line.

    Markers (hollow) are placed on about 12 points per line, shifted and sized by
    ``index`` so that the markers of coinciding lines do not hide one another. A label
    that is not in :data:`STYLES` is styled by ``index``.

    Args:
        method: the method label.
        index: the method's position among the lines of the axes.
        n_points: points on the line (0: no markers).
        lw: line width.
    """
    s = _style(method, index)
    kw: dict[str, Any] = {"color": s.color, "ls": s.ls, "lw": lw}
    if n_points > 0:
        every = max(1, n_points // 12)
        kw |= {
            "marker": s.marker,
            "ms": 4.0 + 1.5 * (index % 4),  # coinciding hollow markers nest as rings
            "markevery": (min(index * every // 5, n_points - 1), every),
            "markerfacecolor": "none",
        }
    return kw


def legend_outside(ax: Any, below: bool = False, **kw: Any) -> Any:
    """A legend outside the data (kept in the figure by constrained layout).

    Args:
        ax: the axes.
        below: under the axes (for long entries) instead of to the right.
        **kw: more ``ax.legend`` arguments.
    """
    if below:
        return ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), borderaxespad=0.0,
                         **kw)
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kw)


def rate_ylim(set_rates: Iterable[float], data: Iterable[ArrayLike] = ()) -> tuple[float, float]:
    """A fixed y range for a rate plot: 0 to 1.3 × the highest set rate.

    Counting noise of one trigger per window then stays a ripple instead of a spike;
    the range grows only to show achieved rates above it.

    Args:
        set_rates: the rates the sources were set to (Hz); non-finite ones are ignored.
        data: the plotted rate series.

    Returns:
        ``(0, top)``.
    """
    finite = [float(r) for r in set_rates if math.isfinite(r) and r > 0]
    top = 1.3 * max(finite) if finite else 0.0
    for ys in data:
        y = np.asarray(ys, dtype=float)
        y = y[np.isfinite(y)]
        if y.size:
            top = max(top, 1.05 * float(y.max()))
    return 0.0, top if top > 0 else 1.0


def spread_shares(values: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The distribution of a frame-spread series: each spread value and its share.

    Args:
        values: spread per render tick (whole frames; NaN ignored).

    Returns:
        ``(levels, shares)``: the distinct spreads, ascending, and the fraction of
        finite ticks at each (summing to 1; both empty if no tick is finite).
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return np.empty(0, dtype=np.int64), np.empty(0)
    levels, counts = np.unique(np.rint(v).astype(np.int64), return_counts=True)
    return levels, counts / counts.sum()
