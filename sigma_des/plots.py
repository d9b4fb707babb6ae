"""Plots of one comparison, written next to its tables by ``compare --out``.

Four PNG files (matplotlib, Agg backend), one curve or violin per method:

* ``aoi_dist.png`` — AoI distribution: violins of the per-render-tick mean AoI over
  nodes, with the p50/p95/p99 of all (render tick × node) samples as markers;
* ``aoi_time.png`` — AoI over time: mean over nodes per render tick, the band up to
  the per-tick maximum;
* ``trigger_rate.png`` — achieved trigger rate over time (triggers issued per second
  in sliding 1 s windows) and, dashed, the rate the trigger source was set to;
* ``spread.png`` — frame spread of the shown snapshot per render tick.

matplotlib is an optional dependency (the ``experiments`` extra): without it
:func:`write_plots` draws nothing and says so in one line.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.outputs import temp_file

if TYPE_CHECKING:
    from sigma_des.api import Results

__all__ = ["PLOTS", "MISSING_NOTE", "have_matplotlib", "rate_series", "write_plots"]

#: File names written by :func:`write_plots`, in order.
PLOTS: tuple[str, ...] = ("aoi_dist.png", "aoi_time.png", "trigger_rate.png", "spread.png")
#: The one-line note when matplotlib is missing.
MISSING_NOTE = (
    "plots skipped: matplotlib is not installed (pip install 'sigma_des[experiments]')"
)
_MS = 1000.0


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


def _aoi_dist(ax: Any, res: Results) -> None:
    names = list(res.methods)
    data = []
    for m in names:
        xs = np.asarray(res.timeseries[m]["aoi_mean"], dtype=float)
        xs = xs[~np.isnan(xs)] * _MS
        data.append(xs)
    pos = np.arange(1, len(names) + 1)
    ok = [i for i, d in enumerate(data) if d.size]
    if ok:
        ax.violinplot([data[i] for i in ok], positions=pos[ok], showmedians=True)
    for q, mk in (("p50", "o"), ("p95", "^"), ("p99", "v")):
        ys = [res.methods[m][f"aoi_{q}"] for m in names]
        ax.scatter(pos + 0.25, ys, marker=mk, color="k", s=18, label=f"{q} of node samples")
    ax.set_xticks(pos, names)
    ax.set_ylabel("AoI (ms)")
    ax.set_title("AoI distribution (violins: per-tick mean over nodes)")
    ax.legend(loc="upper left")


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


_SMOOTH_S = 0.2  # the per-tick mean beats between the render and state rates: smooth it
_STYLES = ("-", "--", ":", "-.")  # methods that coincide stay visible


def _aoi_time(ax: Any, res: Results) -> None:
    n = max(1, round(_SMOOTH_S * res.scenario.f_render))
    for i, m in enumerate(res.methods):
        ts = res.timeseries[m]
        t = np.asarray(ts["t"], dtype=float)
        mean = moving_average(np.asarray(ts["aoi_mean"], dtype=float) * _MS, n)
        mx = moving_average(np.asarray(ts["aoi_max"], dtype=float) * _MS, n)
        ax.plot(t, mean, color=f"C{i}", lw=1.4, ls=_STYLES[i % len(_STYLES)],
                label=f"{m} (mean; band to max)")
        ax.fill_between(t, mean, mx, color=f"C{i}", alpha=0.12, lw=0)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("AoI (ms)")
    ax.set_title(f"AoI over time (mean over nodes, {_SMOOTH_S:g} s moving average)")
    ax.legend(loc="upper right")


def _trigger_rate(ax: Any, res: Results) -> None:
    for i, m in enumerate(res.methods):
        ts = res.timeseries[m]
        t_end, rate = rate_series(ts["t"], ts["latest_trigger"], window=1.0)
        ax.plot(t_end, rate, color=f"C{i}", lw=1.0, label=f"{m} achieved")
        ax.plot(ts["t"], ts["f_trig"], color=f"C{i}", lw=0.8, ls="--")
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("trigger rate (Hz)")
    ax.set_title("Achieved trigger rate (1 s windows; dashed: set rate)")
    ax.legend(loc="lower right")


def _spread(ax: Any, res: Results) -> None:
    for i, m in enumerate(res.methods):
        ts = res.timeseries[m]
        ax.step(ts["t"], ts["spread"], where="post", color=f"C{i}", lw=1.0, label=m)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("frame spread (frames)")
    ax.set_title("Frame spread of the shown snapshot")
    ax.legend(loc="upper right")


_DRAW: dict[str, Callable[[Any, Results], None]] = {
    "aoi_dist.png": _aoi_dist,
    "aoi_time.png": _aoi_time,
    "trigger_rate.png": _trigger_rate,
    "spread.png": _spread,
}


def write_plots(res: Results, out_dir: str | Path) -> list[Path]:
    """Draw :data:`PLOTS` for ``res`` into ``out_dir`` (each saved under a temporary
    name, then renamed).

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
        fig, ax = plt.subplots(figsize=(7.0, 4.0))
        try:
            _DRAW[name](ax, res)
            ax.grid(alpha=0.3)
            fig.tight_layout()
            fd, tmp = temp_file(d, prefix=f".{name}.", suffix=".png")
            os.close(fd)
            try:
                fig.savefig(tmp, dpi=100)
                os.replace(tmp, d / name)
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
        finally:
            plt.close(fig)
        paths.append(d / name)
    return paths
