"""AoI sawtooth integration: a hand-computed case and the M/M/1 FCFS closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.core.rng import Stream
from sigma_des.metrics.aoi import AoITracker


def test_hand_computed_sawtooth() -> None:
    tr = AoITracker(2, t_start=1.0)
    tr.update(0.0, np.array([0]), np.array([0.0]))
    tr.update(0.5, np.array([0]), np.array([0.25]))  # before the window: not a peak
    tr.update(2.0, np.array([0]), np.array([1.5]))  # area [1,2] of t-0.25 = 1.25; peak 1.75
    tr.update(3.0, np.array([0]), np.array([1.0]))  # older than shown: ignored
    tr.update(4.0, np.array([0, 1]), np.array([3.0, 3.5]))  # [2,4] of t-1.5 = 3; peak 2.5
    out = tr.finish(6.0)  # node 0: [4,6] of t-3 = 4; node 1 from 4: [4,6] of t-3.5 = 3
    assert out["time_average"] == (1.25 + 3.0 + 4.0 + 3.0) / (5.0 + 2.0)
    assert out["peak_mean"] == (1.75 + 2.5) / 2
    assert out["peak_count"] == 2
    assert out["nodes"] == 2 and out["node_time"] == 7.0
    np.testing.assert_array_equal(tr.current(6.0), [3.0, 2.5])
    assert tr.finish(6.0) == out  # finish does not modify the tracker


def test_empty_and_unshown_nodes() -> None:
    tr = AoITracker(3, t_start=0.0)
    out = tr.finish(1.0)
    assert math.isnan(out["time_average"]) and math.isnan(out["peak_mean"])
    assert out["peak_count"] == 0 and out["nodes"] == 0
    tr.update(0.5, 2, 0.25)  # scalars accepted
    out = tr.finish(1.0)  # only node 2 counts: [0.5,1] of t-0.25 = 0.25 over 0.5 s
    assert out["time_average"] == 0.5 and out["nodes"] == 1
    assert np.isnan(tr.current(1.0)[:2]).all()


def test_batch_update_keeps_newest_per_node() -> None:
    tr = AoITracker(2, t_start=0.0)
    tr.update(1.0, np.array([0, 1]), np.array([0.5, 0.5]))
    tr.update(2.0, np.array([1, 0, 1]), np.array([1.75, 0.5, 1.5]))  # node 0: not newer
    np.testing.assert_array_equal(tr.current(2.0), [1.5, 0.25])
    out = tr.finish(2.0)
    assert out["peak_count"] == 1 and out["peak_mean"] == 1.5


def test_batch_calls_equal_single_node_calls() -> None:
    rng = np.random.default_rng(3)
    n, steps = 5, 300
    a, b = AoITracker(n, t_start=2.0), AoITracker(n, t_start=2.0)
    gen = np.zeros(n)
    for s in range(steps):
        t = 0.1 * s
        nodes = np.flatnonzero(rng.random(n) < 0.5)
        g = np.minimum(t, gen[nodes] + rng.normal(0.05, 0.1, nodes.size))
        gen[nodes] = np.maximum(gen[nodes], g)
        if nodes.size:
            a.update(t, nodes, g)
        for i, gi in zip(nodes, g, strict=True):
            b.update(t, np.array([i]), np.array([gi]))
    ra, rb = a.finish(31.0), b.finish(31.0)
    assert ra["time_average"] == rb["time_average"]
    assert ra["peak_count"] == rb["peak_count"] > 100
    assert ra["peak_mean"] == pytest.approx(rb["peak_mean"], rel=1e-12)


def test_sorted_unique_nodes_equal_the_deduplicating_path() -> None:
    """Nodes in increasing order skip the de-duplicating sort: the same bits as unsorted."""
    rng = np.random.default_rng(5)
    n = 40
    a, b = AoITracker(n, t_start=0.5), AoITracker(n, t_start=0.5)
    for s in range(60):
        t = 0.05 * s
        nodes = np.flatnonzero(rng.random(n) < 0.6)  # increasing, as Collector.shown's
        g = t - rng.random(nodes.size) * 0.2
        a.update(t, nodes, g)
        b.update(t, nodes[::-1].copy(), g[::-1].copy())  # the lexsort path
        np.testing.assert_array_equal(a.current(t), b.current(t))
    assert a.finish(3.0) == b.finish(3.0)
    assert a.finish(3.0)["peak_count"] > 500


def test_time_order_enforced() -> None:
    tr = AoITracker(1, t_start=0.0)
    tr.update(2.0, 0, 1.0)
    with pytest.raises(ValueError):
        tr.update(1.0, 0, 1.5)
    with pytest.raises(ValueError):
        tr.finish(1.5)


@pytest.mark.parametrize(("rho", "max_rel_se"), [(0.5, 0.01), (0.8, 0.03)])
def test_mm1_fcfs_closed_form(rho: float, max_rel_se: float) -> None:
    mu, lam, n = 1.0, rho, 200_000
    s = Stream(2024, "mm1")
    k = np.arange(n)
    arrival = np.cumsum(s.exponential(k, 0) / lam)
    service = s.exponential(k, 1) / mu
    # Lindley: d_k = max(a_k, d_{k-1}) + S_k  <=>  d_k = C_k + max_{j<=k}(a_j - C_{j-1})
    c = np.cumsum(service)
    depart = c + np.maximum.accumulate(arrival - (c - service))
    t_start = float(depart[1000])  # warm-up
    tr = AoITracker(1, t_start=t_start)
    node = np.array([0])
    for d, a in zip(depart.tolist(), arrival.tolist(), strict=True):
        tr.update(d, node, np.array([a]))
    out = tr.finish(float(depart[-1]))

    # Independent computation of the same sawtooth, in 20 batches for the error bar.
    lo, hi, g = depart[1000:-1], depart[1001:], arrival[1000:-1]
    area = (hi - lo) * ((hi + lo) / 2 - g)
    assert out["time_average"] == pytest.approx(area.sum() / (hi - lo).sum(), rel=1e-9)
    batches = np.array_split(np.arange(area.size), 20)
    means = np.array([area[b].sum() / (hi[b] - lo[b]).sum() for b in batches])
    se = means.std(ddof=1) / math.sqrt(means.size)

    theory = (1 / mu) * (1 + 1 / rho + rho**2 / (1 - rho))  # 3.5 (rho .5), 5.45 (rho .8)
    # Batches of 10k departures are far longer than the queue's correlation time
    # (~1/(1 - sqrt(rho))^2 ≈ 90 services at rho = 0.8), so batch means are close to
    # independent. With 2e5 updates the relative SE is ~0.3 % (rho 0.5) and ~2.4 %
    # (rho 0.8, long busy periods): precise enough that a wrong integral fails.
    assert se < max_rel_se * theory
    assert abs(out["time_average"] - theory) < 4 * se
    # Peak AoI of M/M/1 FCFS: 1/lambda + 1/(mu - lambda)
    assert out["peak_count"] == n - 1000  # updates at t >= t_start (depart[1000] on)
    assert out["peak_mean"] == pytest.approx(1 / lam + 1 / (mu - lam), rel=0.03)


def test_deliveries_per_s_counts_each_receiver_once() -> None:
    """Issue 9.4: the tiny scenario (3 nodes, 100 Hz, no commands, no loss) delivers
    every trigger to 3 nodes and every state to the server: 300 + 300 per second."""
    from sigma_des import compare
    from tests.conftest import tiny

    for engine in ("events", "cohort"):
        m = compare(tiny(engine=engine), ["none"], progress=False).methods["none"]
        assert m["deliveries_per_s"] == 600.0
        assert "messages_per_s" not in m
