"""The capacity search on synthetic monotone predictors, by hand; the budget predicate;
the hosts rule."""

from __future__ import annotations

import math

import pytest

from sigma_des.calibrate.capacity import HostsRule, find_capacity, holds, search
from sigma_des.calibrate.intervals import Interval
from sigma_des.errors import ConfigError


def test_search_doubles_then_bisects_to_the_hand_computed_capacity() -> None:
    # holds up to 37: 10, 20 hold, 40 fails; bisect 30 ok, 35 ok, 37 ok, 38 fails;
    # then 38 - 37 = 1 <= max(1, 0.05 x 37): stop
    assert search(lambda n: n <= 37, 10, 400) == (37, 38, [10, 20, 40, 30, 35, 37, 38])
    # bounded: 4 evaluations
    assert search(lambda n: n <= 37, 10, 400, max_evals=4) == (30, 40, [10, 20, 40, 30])
    assert search(lambda n: False, 10, 400) == (None, 10, [10])
    assert search(lambda n: True, 10, 400) == (400, None, [10, 20, 40, 80, 160, 320, 400])


def test_holds_budgets() -> None:
    assert holds(99.0, 0.05, 30.0, 100.0, 0.05, None)
    assert not holds(94.0, 0.0, 1.0, 100.0, 0.05, None)  # rate below 95 %
    assert not holds(100.0, 0.051, 1.0, 100.0, 0.05, None)
    assert not holds(100.0, 0.0, 12.0, 100.0, 0.05, 10.0)
    assert holds(100.0, 0.0, math.nan, 100.0, 0.05, None)  # no latency budget
    assert not holds(100.0, math.nan, 1.0, 100.0, 0.05, None)


def _iv(mean: float, lo: float, hi: float) -> Interval:
    return Interval(mean, 0.0, lo, hi, None)


def test_find_capacity_means_and_interval_ends_share_one_cache() -> None:
    """Missed frames n / 1000 (interval n / 2000 .. n / 500), rate held: at 5 % the
    means hold to 50, the pessimistic end to 25, the optimistic to 100."""
    calls: list[int] = []

    def at(n: int) -> dict[str, Interval]:
        calls.append(n)
        return {"trigger_rate_hz": _iv(100.0, 99.0, 101.0),
                "missed_frac": _iv(n / 1000, n / 2000, n / 500),
                "latency_state_mean": _iv(1.0, 0.5, 2.0)}

    c = find_capacity("none", at, 10, 400, 100.0, 0.05, None)
    # means: 10 20 40 ok, 80 fails; 60 fails, 50 ok, 55 fails, 52 fails; 52 - 50 <= 2.5
    assert (c.capacity, c.first_failing, c.evaluated) == (50, 52, [10, 20, 40, 80, 60, 50,
                                                                   55, 52])
    # pessimistic: 10 20 ok, 40 fails; 30 fails, 25 ok, 27 fails, 26 fails -> 25
    # optimistic: 10..80 ok, 160 fails; 120 fails, 100 ok, 110 fails, 105 fails,
    # 102 fails -> 100 (102 - 100 <= 5)
    assert (c.lo, c.hi) == (25, 100)
    assert len(calls) == len(set(calls)) == len(c.points)  # each N predicted once
    assert c.points[50]["missed_frac"].mean == 0.05


def test_hosts_rule() -> None:
    assert [HostsRule.parse("validation", 2).hosts(n) for n in (10, 50, 51, 100)] == [2, 2, 3, 4]
    assert HostsRule.parse("fixed", 4).hosts(100) == 4
    assert HostsRule.parse("fixed", 4).hosts(3) == 3
    assert HostsRule.parse("per=8", 2).hosts(33) == 5
    for bad in ("per=0", "per=x", "auto"):
        with pytest.raises(ConfigError, match="--hosts-rule"):
            HostsRule.parse(bad, 2)


def test_search_on_a_grid_by_hand() -> None:
    grid = [10, 20, 30, 40, 50, 60, 80, 100, 120, 150]
    # positions 0, 1, 3 hold, 7 (100) fails; bisect: 5 (60) fails, 4 (50) holds: adjacent
    assert search(lambda n: n <= 55, 0, 0, grid=grid) == (50, 60, [10, 20, 40, 100, 60, 50])
    assert search(lambda n: True, 0, 0, grid=grid) == (150, None, [10, 20, 40, 100, 150])
    assert search(lambda n: False, 0, 0, grid=grid) == (None, 10, [10])
    assert search(lambda n: n < 20, 0, 0, grid=grid) == (10, 20, [10, 20])


def test_search_brackets_every_threshold() -> None:
    """For every threshold T of a monotone predicate: capacity <= T < first failing,
    within the tolerance, in at most 16 evaluations (10..400: 6 doublings, then
    bisection of a bracket of at most 200)."""
    for t in range(10, 400):
        cap, bad, seen = search(lambda n, t=t: n <= t, 10, 400)
        assert cap is not None and bad is not None and len(seen) <= 16
        assert cap <= t < bad and bad - cap <= max(1.0, 0.05 * cap)


def test_figure_draws_rate_missed_and_latency_with_the_budgets() -> None:
    """Three panels against N: rate as % of nominal (95 % line), missed frames (the
    budget), latency (its budget), the budgets in black; the capacity dotted; plain
    node-count ticks."""
    import matplotlib.pyplot as plt

    from sigma_des.calibrate.capacity import Capacity, figure

    pts = {n: {"trigger_rate_hz": _iv(50.0 - n / 10, 49.0 - n / 10, 51.0),
               "missed_frac": _iv(n / 1000, n / 2000, n / 500),
               "latency_state_mean": _iv(1.0 + n, 0.5 + n, 2.0 + n)} for n in (10, 20, 40)}
    fig = figure([Capacity("lockstep", 20, 40, 10, 40, [10, 20, 40], pts)], 0.05, 30.0, 50.0)
    try:
        rate, missed, lat = fig.axes
        assert [a.get_ylabel() for a in fig.axes] == [
            "trigger rate (% of nominal)", "missed frames (%)", "mean state latency (ms)"]
        curve = rate.lines[0]
        assert list(curve.get_xdata()) == [10, 20, 40]
        assert list(curve.get_ydata()) == pytest.approx([98.0, 96.0, 92.0])  # 100 x rate / 50
        assert list(missed.lines[0].get_ydata()) == pytest.approx([1.0, 2.0, 4.0])

        def hlines(ax: object) -> list[float]:
            return [ln.get_ydata()[0] for ln in ax.lines  # type: ignore[attr-defined]
                    if ln.get_color() == "k"]

        def vlines(ax: object) -> list[float]:
            return [ln.get_xdata()[0] for ln in ax.lines  # type: ignore[attr-defined]
                    if ln.get_linestyle() == ":"]

        assert hlines(rate) == [95.0] and hlines(missed) == [5.0] and hlines(lat) == [30.0]
        assert vlines(rate) == vlines(missed) == vlines(lat) == [20]
        fig.canvas.draw()
        assert [t.get_text() for t in rate.get_xticklabels()] == ["10", "20", "30"]
        assert lat.get_yscale() == "log" and rate.get_xscale() == "log"
    finally:
        plt.close(fig)
