"""Plots of one comparison, written next to its tables by ``compare --out``.

Four PNG files (matplotlib, Agg backend), one curve or violin per method, every
method in its :mod:`sigma_des.plotstyle` colour, line style and marker (the same as in
the study plots); legends sit to the right of the data, and a method whose curve
coincides with an earlier one is named in the legend as ``"lockstep (= bides)"``:

* ``aoi_dist.png`` — AoI distribution: violins of the per-render-tick mean AoI over
  nodes, with the p50/p95/p99 of all (render tick × node) samples as markers;
* ``aoi_time.png`` — AoI over time: mean over nodes per render tick, the band up to
  the per-tick maximum;
* ``trigger_rate.png`` — achieved trigger rate over time (triggers issued per second
  in sliding 1 s windows) and, thin, the rate the trigger source was set to, on a
  fixed axis from 0 to 1.3 × the set rate (:func:`~sigma_des.plotstyle.rate_ylim`);
* ``spread.png`` — frame spread of the shown snapshot: its distribution over render
  ticks (share of ticks per spread) and its moving mean over time.

matplotlib is an optional dependency (the ``experiments`` extra): without it
:func:`write_plots` draws nothing and says so in one line.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.guard import atomic_write
from sigma_des.plotstyle import (
    MIN_DPI,
    coinciding,
    legend_outside,
    line_kw,
    method_label,
    rate_ylim,
    spread_shares,
)

if TYPE_CHECKING:
    from sigma_des.api import Results

__all__ = [
    "PLOTS",
    "MISSING_NOTE",
    "aoi_violins",
    "draw",
    "have_matplotlib",
    "moving_average",
    "plot_lines",
    "rate_series",
    "write_plots",
]

#: File names written by :func:`write_plots`, in order.
PLOTS: tuple[str, ...] = ("aoi_dist.png", "aoi_time.png", "trigger_rate.png", "spread.png")
#: The one-line note when matplotlib is missing.
MISSING_NOTE = (
    "plots skipped: matplotlib is not installed (pip install 'sigma_des[experiments]')"
)
_MS = 1000.0
_SMOOTH_S = 0.2  # the per-tick mean beats between the render and state rates: smooth it
_SPREAD_SMOOTH_S = 0.5  # spread alternates tick by tick: show its moving mean


def have_matplotlib() -> bool:
    """True if matplotlib can be imported."""
    return importlib.util.find_spec("matplotlib") is not None


def rate_series(
    t: NDArray[np.float64], counter: NDArray[np.float64], window: float = 0.25
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Advance rate of a counter (per second) over sliding windows of ``window`` s.

    Args:
        t: sample times (s), increasing and evenly spaced.
        counter: the counter at those times (e.g. the newest trigger index).
        window: window length (s).

    Returns:
        ``(t_end, rate)``: window end times and the counter's advance per second.
    """
    t = np.asarray(t, dtype=float)
    f = np.asarray(counter, dtype=float)
    if t.size < 2:
        return np.empty(0), np.empty(0)
    dt = float(np.median(np.diff(t)))
    step = max(1, round(window / dt)) if dt > 0 else 1
    step = min(step, t.size - 1)
    return t[step:], (f[step:] - f[:-step]) / (t[step:] - t[:-step])


def moving_average(x: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Centred moving average over ``n`` samples, ignoring NaNs (same length as ``x``).

    Near the ends the window holds fewer samples; a window with no finite sample is NaN.
    """
    n = min(n, x.size)  # np.convolve's "same" is as long as the longer input
    if n <= 1:
        return x.astype(float)
    ok = np.isfinite(x)
    k = np.ones(n)
    num = np.convolve(np.where(ok, x, 0.0), k, mode="same")
    cnt = np.convolve(ok.astype(float), k, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, num / np.where(cnt > 0, cnt, 1.0), np.nan)


def plot_lines(
    ax: Any,
    series: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]],
    suffix: str = "",
    lw: float = 1.3,
) -> dict[str, str]:
    """One line per method in its house style; coinciding methods named in the legend.

    Args:
        ax: the axes.
        series: method -> ``(x, y)``.
        suffix: appended to each method's legend entry.
        lw: line width.

    Returns:
        The coinciding methods (see :func:`~sigma_des.plotstyle.coinciding`).
    """
    twins = coinciding({m: y for m, (_, y) in series.items()})
    for i, (m, (x, y)) in enumerate(series.items()):
        ax.plot(x, y, label=method_label(m, twins, suffix), **line_kw(m, i, len(y), lw))
    return twins


def aoi_violins(
    ax: Any, data: dict[str, NDArray[np.float64]], tails: dict[str, list[float]]
) -> None:
    """Violins of per-tick mean AoI per method, with tail markers beside each.

    Args:
        ax: the axes.
        data: method -> AoI samples (ms; NaN ignored), one violin each.
        tails: ``"p50"``/``"p95"``/``"p99"`` -> one value per method (ms), drawn as
            black markers to the right of the violins.
    """
    names = list(data)
    clean = [d[np.isfinite(d)] for d in data.values()]
    pos = np.arange(1, len(names) + 1)
    ok = [i for i, d in enumerate(clean) if d.size]
    if ok:
        parts = ax.violinplot([clean[i] for i in ok], positions=pos[ok], showmedians=True)
        for body, i in zip(parts["bodies"], ok, strict=True):
            body.set_facecolor(line_kw(names[i], i)["color"])
            body.set_alpha(0.55)
        for key in ("cmedians", "cmins", "cmaxes", "cbars"):
            parts[key].set_color("k")
            parts[key].set_linewidth(0.8)
    for q, mk in (("p50", "o"), ("p95", "^"), ("p99", "v")):
        if q in tails:
            ax.scatter(pos + 0.25, tails[q], marker=mk, color="k", s=18,
                       label=f"{q} of node samples")
    ax.set_xticks(pos, names)
    ax.set_ylabel("AoI (ms)")
    legend_outside(ax)


def _aoi_dist(fig: Any, res: Results) -> None:
    ax = fig.subplots()
    data = {m: np.asarray(res.timeseries[m]["aoi_mean"], dtype=float) * _MS for m in res.methods}
    tails = {q: [res.methods[m][f"aoi_{q}"] for m in res.methods] for q in ("p50", "p95", "p99")}
    aoi_violins(ax, data, tails)
    ax.set_title("AoI distribution (violins: per-tick mean over nodes; median line)")


def _time_label(res: Results) -> str:
    """The x axis of a time plot: a live run's clock is the wall clock, not simulated time."""
    return "run time (s, wall clock)" if res.mode == "live" else "simulated time (s)"


def _aoi_time(fig: Any, res: Results) -> None:
    ax = fig.subplots()
    n = max(1, round(_SMOOTH_S * res.scenario.f_render))
    series = {}
    for m in res.methods:
        ts = res.timeseries[m]
        t = np.asarray(ts["t"], dtype=float)
        series[m] = (t, moving_average(np.asarray(ts["aoi_mean"], dtype=float) * _MS, n))
    plot_lines(ax, series, " (mean)")
    for i, (m, (t, mean)) in enumerate(series.items()):
        mx = moving_average(np.asarray(res.timeseries[m]["aoi_max"], dtype=float) * _MS, n)
        ax.fill_between(t, mean, mx, color=line_kw(m, i)["color"], alpha=0.12, lw=0)
    ax.set_xlabel(_time_label(res))
    ax.set_ylabel("AoI (ms)")
    ax.set_title(f"AoI over time (mean over nodes, band to max; {_SMOOTH_S:g} s moving mean)")
    legend_outside(ax)


def _trigger_rate(fig: Any, res: Results) -> None:
    ax = fig.subplots()
    achieved, set_rate = {}, {}
    for m in res.methods:
        ts = res.timeseries[m]
        achieved[m] = rate_series(ts["t"], ts["latest_trigger"], window=1.0)
        set_rate[m] = (np.asarray(ts["t"], dtype=float), np.asarray(ts["f_trig"], dtype=float))
    plot_lines(ax, achieved, " achieved")
    same = coinciding({m: y for m, (_, y) in set_rate.items()})
    if len(set_rate) > 1 and len(same) == len(set_rate) - 1:
        t, y = next(iter(set_rate.values()))  # every method was set alike: one line
        ax.plot(t, y, color="k", ls="--", lw=0.8, label="set rate (all methods)")
    else:
        plot_lines(ax, set_rate, " set", lw=0.7)
    ax.set_ylim(*rate_ylim(
        [float(np.nanmax(y)) for _, y in set_rate.values() if np.isfinite(y).any()],
        [y for _, y in achieved.values()],
    ))
    ax.set_xlabel(_time_label(res))
    ax.set_ylabel("trigger rate (Hz)")
    ax.set_title("Trigger rate: achieved (1 s windows) and set")
    legend_outside(ax)


def _spread(fig: Any, res: Results) -> None:
    ax_d, ax_t = fig.subplots(1, 2, width_ratios=(1, 1.6))
    names = list(res.methods)
    shares = {m: spread_shares(res.timeseries[m]["spread"]) for m in names}
    width = 0.8 / max(1, len(names))
    for i, m in enumerate(names):
        levels, share = shares[m]
        ax_d.bar(levels + (i - (len(names) - 1) / 2) * width, share, width=width,
                 color=line_kw(m, i)["color"], label=m)
    all_levels = sorted({int(v) for lv, _ in shares.values() for v in lv})
    ax_d.set_xticks(all_levels)
    ax_d.set_xlabel("frame spread (frames)")
    ax_d.set_ylabel("share of render ticks")
    ax_d.set_ylim(0, 1.05)
    ax_d.set_title("Distribution")
    n = max(1, round(_SPREAD_SMOOTH_S * res.scenario.f_render))
    series = {}
    for m in names:
        ts = res.timeseries[m]
        y = moving_average(np.asarray(ts["spread"], dtype=float), n)
        series[m] = (np.asarray(ts["t"], dtype=float), y)
    plot_lines(ax_t, series)
    ax_t.set_xlabel(_time_label(res))
    ax_t.set_ylabel("frame spread (frames)")
    ax_t.set_title(f"{_SPREAD_SMOOTH_S:g} s moving mean")
    fig.suptitle("Frame spread of the shown snapshot")
    legend_outside(ax_t)


_DRAW: dict[str, Callable[[Any, Results], None]] = {
    "aoi_dist.png": _aoi_dist,
    "aoi_time.png": _aoi_time,
    "trigger_rate.png": _trigger_rate,
    "spread.png": _spread,
}


def draw(name: str, res: Results) -> Any:
    """The matplotlib figure of plot ``name`` (one of :data:`PLOTS`) for ``res``.

    The caller closes it (``plt.close(fig)``); needs matplotlib.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(9.0, 4.0), dpi=MIN_DPI, layout="constrained")
    try:
        _DRAW[name](fig, res)
    except BaseException:
        plt.close(fig)
        raise
    for ax in fig.axes:
        ax.grid(alpha=0.3)
    return fig


def write_plots(res: Results, out_dir: str | Path) -> list[Path]:
    """Draw :data:`PLOTS` for ``res`` into ``out_dir`` (each saved under a temporary
    name, fsynced, then renamed, readable as the umask says).

    Args:
        res: the comparison.
        out_dir: an existing, writable directory.

    Returns:
        The files written; empty if matplotlib is missing (see :data:`MISSING_NOTE`).
    """
    if not have_matplotlib():
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = Path(out_dir)
    paths = []
    for name in PLOTS:
        fig = draw(name, res)
        try:  # temporary name, fsync, rename, the umask's mode
            atomic_write(d / name, partial(fig.savefig, format="png", dpi=MIN_DPI), "--out",
                         binary=True)
        finally:
            plt.close(fig)
        paths.append(d / name)
    return paths
