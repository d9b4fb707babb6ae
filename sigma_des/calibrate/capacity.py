"""``sigma-des capacity``: the largest N each method holds, by a bounded search with ``predict``.

A method **holds** N (:func:`holds`) when its achieved trigger rate is at least
:data:`RATE_HELD` of the nominal one, at most ``max_missed`` of the frames' states are
missed and (with a latency budget) the mean state latency is within it. The same
function decides the knee the validation suite scores, for live's runs and for the DES.

:func:`search` finds the largest N that holds, on a monotone predicate, in a bounded
number of evaluations: from ``n_lo`` it doubles N until it fails (or reaches
``n_max``), then bisects between the last N that held and the first that failed until
they are within ``tol`` of each other (relative, at least one node). Each method gets
three searches sharing one cache of predictions: on the predicted means, and on each
end of their intervals (the pessimistic end: the interval's high missed fraction and
latency, its low rate; the optimistic end the other way), which gives the capacity's
interval. :func:`plot` draws the achieved rate, missed frames and mean latency
against N per method, the capacity marked.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sigma_des.calibrate.intervals import RATE_HELD, Interval
from sigma_des.errors import ConfigError

__all__ = ["MAX_EVALS", "RATE_HELD", "Capacity", "HostsRule", "find_capacity", "holds",
           "figure", "holds_at", "plot", "search"]

#: Most predictions one search makes.
MAX_EVALS = 16


def holds(rate: float, missed: float, latency_ms: float, f_trig: float, max_missed: float,
          max_latency_ms: float | None) -> bool:
    """Does a run with these figures hold (see the module doc)? A NaN figure fails."""
    vals = [rate, missed] + ([latency_ms] if max_latency_ms is not None else [])
    if not all(math.isfinite(v) for v in vals):
        return False
    ok = rate >= RATE_HELD * f_trig and missed <= max_missed
    return ok and (max_latency_ms is None or latency_ms <= max_latency_ms)


def holds_at(ivs: dict[str, Interval], end: str, f_trig: float, max_missed: float,
             max_latency_ms: float | None) -> bool:
    """:func:`holds` on a prediction's intervals: ``end`` ``mean``, ``pessimistic`` (high
    missed and latency, low rate) or ``optimistic`` (the other ends)."""
    r, m, la = ivs["trigger_rate_hz"], ivs["missed_frac"], ivs["latency_state_mean"]
    if end == "mean":
        return holds(r.mean, m.mean, la.mean, f_trig, max_missed, max_latency_ms)
    if end == "pessimistic":
        return holds(r.lo, m.hi, la.hi, f_trig, max_missed, max_latency_ms)
    return holds(r.hi, m.lo, la.lo, f_trig, max_missed, max_latency_ms)


def search(ok: Callable[[int], bool], n_lo: int, n_max: int, tol: float = 0.05,
           max_evals: int = MAX_EVALS, grid: Sequence[int] | None = None
           ) -> tuple[int | None, int | None, list[int]]:
    """The largest N in ``n_lo..n_max`` for which ``ok`` holds (see the module doc).

    Args:
        ok: the predicate, assumed monotone (holds up to some N, fails beyond).
        n_lo: the first N tried; n_max: the largest.
        tol: bisection stops when the bracket is within ``tol`` x N (at least 1).
        max_evals: most evaluations.
        grid: search only these N (sorted; ``n_lo``/``n_max`` then unused): the same
            doubling and bisection over their positions, to the neighbouring point
            (the validation suite's grids).

    Returns:
        ``(capacity, first_failing, evaluated)``: capacity None when the first N fails;
        first_failing None when the last holds; the N evaluated, in order.
    """
    pts = sorted(set(grid)) if grid is not None else None
    seen: list[int] = []

    def test(i: int) -> bool:
        n = pts[i] if pts is not None else i
        seen.append(n)
        return ok(n)

    def at(i: int | None) -> int | None:
        return None if i is None or pts is None else pts[i]

    lo, top = (0, len(pts) - 1) if pts is not None else (n_lo, n_max)
    if pts is not None and not pts:
        return None, None, seen
    if not test(lo):
        return (None, at(lo), seen) if pts is not None else (None, lo, seen)
    good, bad, i = lo, None, lo
    while bad is None and i < top and len(seen) < max_evals:
        i = min(top, 2 * i if pts is None else 2 * i + 1)
        if test(i):
            good = i
        else:
            bad = i
    width = 1.0 if pts is not None else None
    while bad is not None and len(seen) < max_evals and (
            bad - good > (width or max(1.0, tol * good))):
        mid = (good + bad) // 2
        if test(mid):
            good = mid
        else:
            bad = mid
    if pts is not None:
        return at(good), at(bad), seen
    return good, bad, seen


@dataclass(frozen=True)
class HostsRule:
    """How many hosts a target of N nodes runs on: ``validation`` (``max(2, ceil(N /
    25))``, the validation grid's), ``fixed`` (the calibration's) or ``per=K``
    (``ceil(N / K)``)."""

    kind: str
    per: int = 25
    fixed: int = 1

    @staticmethod
    def parse(text: str, fixed: int) -> HostsRule:
        """``--hosts-rule``.

        Raises:
            ConfigError: (``--hosts-rule``) anything else.
        """
        if text in ("validation", "fixed"):
            return HostsRule(text, fixed=fixed)
        if text.startswith("per="):
            try:
                k = int(text[4:])
            except ValueError:
                k = 0
            if k >= 1:
                return HostsRule("per", per=k)
        raise ConfigError("--hosts-rule", f"must be validation, fixed or per=K (K >= 1 "
                          f"nodes per host), got {text!r}")

    def hosts(self, nodes: int) -> int:
        """Host processes for ``nodes``."""
        if self.kind == "fixed":
            return min(self.fixed, nodes)
        if self.kind == "per":
            return max(1, math.ceil(nodes / self.per))
        return max(2, math.ceil(nodes / 25))


@dataclass
class Capacity:
    """One method's capacity: the search on the means and on each end of the intervals."""

    method: str
    capacity: int | None
    first_failing: int | None
    lo: int | None
    hi: int | None
    evaluated: list[int] = field(default_factory=list)
    points: dict[int, dict[str, Any]] = field(default_factory=dict)


def find_capacity(method: str, predict_at: Callable[[int], dict[str, Interval]], n_lo: int,
                  n_max: int, f_trig: float, max_missed: float, max_latency_ms: float | None,
                  max_evals: int = MAX_EVALS) -> Capacity:
    """``method``'s capacity and its interval: three :func:`search` es (the means, the
    pessimistic and the optimistic ends) over one cache of ``predict_at(N)``."""
    cache: dict[int, dict[str, Interval]] = {}

    def at(n: int) -> dict[str, Interval]:
        if n not in cache:
            cache[n] = predict_at(n)
        return cache[n]

    def ok(end: str) -> Callable[[int], bool]:
        return lambda n: holds_at(at(n), end, f_trig, max_missed, max_latency_ms)

    cap, bad, seen = search(ok("mean"), n_lo, n_max, max_evals=max_evals)
    lo, _, _ = search(ok("pessimistic"), n_lo, n_max, max_evals=max_evals)
    hi, _, _ = search(ok("optimistic"), n_lo, n_max, max_evals=max_evals)
    return Capacity(method, cap, bad, lo, hi, seen, dict(sorted(cache.items())))


def figure(caps: list[Capacity], max_missed: float, max_latency_ms: float | None,
           f_trig: float) -> Any:
    """The capacity figure (matplotlib ``Figure``): per method against N, the achieved
    trigger rate (% of nominal, the 95 % line), the missed frames and the mean state
    latency, each with its interval band, the capacity dotted, the budgets in black.

    The rate panel shows why a method whose missed frames and latency stay low still
    stops holding (Lock-Step's barrier lowers its rate instead of missing frames).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    from sigma_des.plotstyle import line_kw

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2), layout="constrained")
    panels = (("trigger_rate_hz", 100.0 / f_trig, "trigger rate (% of nominal)", False),
              ("missed_frac", 100.0, "missed frames (%)", False),
              ("latency_state_mean", 1.0, "mean state latency (ms)", True))
    for c in caps:
        ns = sorted(c.points)
        kw = line_kw(c.method, n_points=len(ns))
        for ax, (k, scale, _label, _log) in zip(axes, panels, strict=True):
            ivs = [c.points[n][k] for n in ns]
            ax.plot(ns, [scale * iv.mean for iv in ivs], label=c.method, **kw)
            ax.fill_between(ns, [scale * iv.lo for iv in ivs], [scale * iv.hi for iv in ivs],
                            color=kw["color"], alpha=0.12, lw=0)
            if c.capacity is not None:
                ax.axvline(c.capacity, color=kw["color"], ls=":", lw=1)
    # the budgets: thin black lines (the methods' own styles use dashes)
    axes[0].axhline(100 * RATE_HELD, color="k", lw=0.8)
    axes[1].axhline(100 * max_missed, color="k", lw=0.8)
    if max_latency_ms is not None:
        axes[2].axhline(max_latency_ms, color="k", lw=0.8)
    for ax, (_k, _s, label, log) in zip(axes, panels, strict=True):
        ax.set_ylabel(label)
        ax.set_xlabel("nodes N")
        ax.set_xscale("log")
        # plain node counts on the log axis (10, 20, 50, not 2 x 10^1)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xticks(_ticks(caps))
        if log:
            ax.set_yscale("log")
    axes[0].legend(title="dotted: capacity; black: budget", fontsize=8)
    return fig


def _ticks(caps: list[Capacity]) -> list[int]:
    """Round node counts within the evaluated range, for the log N axis."""
    ns = [n for c in caps for n in c.points]
    if not ns:
        return []
    lo, hi = min(ns), max(ns)
    marks = [m * 10**e for e in range(0, 6) for m in (1, 2, 3, 5)]
    inside = [m for m in marks if lo <= m <= hi]
    return sorted({lo, hi, *inside}) if len(inside) < 2 else inside


def plot(caps: list[Capacity], path: Path, max_missed: float,
         max_latency_ms: float | None, f_trig: float) -> None:
    """:func:`figure` written to ``path`` (PNG)."""
    import matplotlib.pyplot as plt

    from sigma_des.plotstyle import MIN_DPI

    fig = figure(caps, max_missed, max_latency_ms, f_trig)
    fig.savefig(path, dpi=max(MIN_DPI, 110))
    plt.close(fig)
