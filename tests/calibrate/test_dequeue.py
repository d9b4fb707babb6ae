"""De-queuing in-order latencies: hand-computed Kaplan–Meier masses, and a synthetic
in-order stream whose underlying hop draws the de-queuing recovers (the raw latencies,
resampled through the same in-order stream, count the wait twice)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sigma_des.calibrate.dequeue import censored_weights, dequeued, held, quantiles, sender_waits
from sigma_des.core.rng import RandomStreams


def _in_order(s: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Deliveries of one in-order connection: D_k = max(s_k + d_k, D_{k-1})."""
    return np.maximum.accumulate(s + d)


def test_held_flags_deliveries_behind_an_earlier_sent_message() -> None:
    # sends 0, 1, 2, 3; draws 2.5, 0.5, 2, 0.2 -> arrivals 2.5, 1.5, 4, 3.2 -> D 2.5 2.5 4 4
    s = np.array([0.0, 1.0, 2.0, 3.0])
    d_true = np.array([2.5, 0.5, 2.0, 0.2])
    dl = _in_order(s, d_true)
    assert dl.tolist() == [2.5, 2.5, 4.0, 4.0]
    assert held(np.zeros(4), s, dl, tol=0.0).tolist() == [False, True, False, True]
    # an unheld message's latency is its draw, exactly
    h = held(np.zeros(4), s, dl, tol=0.0)
    assert np.array_equal((dl - s)[~h], d_true[~h])
    # two connections are independent; the order of the rows does not matter
    conn = np.array([0, 1, 0, 1])
    perm = np.array([3, 1, 0, 2])
    assert held(conn[perm], s[perm], dl[perm], tol=0.0).tolist() == [False, False, False, False]
    # within tol after the latest earlier delivery counts as held
    assert held(np.zeros(2), [0.0, 0.001], [0.002, 0.00205], tol=1e-4).tolist() == [False, True]


def test_held_with_a_receiver_thread_hand_computed() -> None:
    """``service`` = 1 ms per delivery: receipts at 0, 0.2, 0.4, 2.5, 3.3 and 10 ms on
    one connection. The thread is busy until 1, 2, 3 ms after the first three; the
    fourth (2.5) comes while it is still busy (until 3): held, though 2.1 ms after the
    previous receipt; it keeps the thread until 4, so the fifth (3.3) is held too; the
    sixth finds it idle. Without a service only gaps within ``tol`` count."""
    r = np.array([0.0, 0.2, 0.4, 2.5, 3.3, 10.0]) * 1e-3
    s = r - 1e-3
    got = held(np.zeros(6), s, r, tol=0.0, service=1e-3)
    assert got.tolist() == [False, True, True, True, True, False]
    assert held(np.zeros(6), s, r, tol=2.5e-4).tolist() == [False, True, True, False, False,
                                                            False]
    # a second connection starts idle: its first delivery (2.5) is not held, its second
    # (3.3, within the first's 1 ms) is
    conn = np.array([0, 0, 0, 1, 1, 1])
    got2 = held(conn, s, r, tol=0.0, service=1e-3)
    assert got2.tolist() == [False, True, True, False, True, False]


def test_redistribution_to_the_left_by_hand() -> None:
    # latencies 2.5, 1.5 (held), 2, 1 (held): events 2 and 2.5 keep 1/4 each; 1.5's quarter
    # goes to the one sample below it (1, itself held), which has nowhere to go: 1/2 at 1
    xs, w = censored_weights([2.5, 1.5, 2.0, 1.0], [False, True, False, True])
    assert xs.tolist() == [1.0, 1.5, 2.0, 2.5]
    assert w.tolist() == [0.5, 0.0, 0.25, 0.25]
    # a held sample spreads equally over everything below it (events first at a tie)
    xs, w = censored_weights([1.0, 2.0, 3.0, 3.0], [False, False, True, False])
    assert xs.tolist() == [1.0, 2.0, 3.0, 3.0]
    assert w == pytest.approx([0.25 + 0.25 / 3, 0.25 + 0.25 / 3, 0.25 + 0.25 / 3, 0.0])
    # nothing held: the plain empirical distribution
    xs, w = censored_weights([3.0, 1.0, 2.0], [False] * 3)
    assert xs.tolist() == [1.0, 2.0, 3.0] and w == pytest.approx([1 / 3] * 3)
    assert quantiles([1.0, 2.0, 3.0], [0.5, 0.25, 0.25], 4).tolist() == [1.0, 1.0, 2.0, 3.0]


def test_dequeuing_recovers_the_hop_draws_of_a_synthetic_in_order_stream() -> None:
    # bursts of 5 messages 2 us apart every 10 ms (a host's states), draws 0.5 ms + Exp(2 ms)
    n = 20_000
    k = np.arange(n)
    st = RandomStreams(7).stream("dequeue")
    s = (k // 5) * 0.01 + (k % 5) * 2e-6
    d = 0.0005 + 0.002 * st.exponential(k)
    dl = _in_order(s, d)
    lat = dl - s
    q, frac = dequeued(np.zeros(n), s, dl, tol=0.0)
    assert 0.4 < frac < 0.7  # in-order holds are common here
    assert lat.mean() > 1.5 * d.mean()  # the measured latency carries the wait
    assert q.mean() == pytest.approx(d.mean(), rel=0.01)
    for p in (10, 50, 90, 99):
        assert np.percentile(q, p) == pytest.approx(np.percentile(d, p), rel=0.03)
    # resampled into the same in-order stream, the de-queued draws give back the measured
    # latencies; the raw latencies count the wait twice
    u = np.floor(st.uniform(k + n) * n).astype(np.int64)
    again = _in_order(s, q[u]) - s
    twice = _in_order(s, np.sort(lat)[u]) - s
    assert again.mean() == pytest.approx(lat.mean(), rel=0.02)
    assert twice.mean() > 1.3 * lat.mean()


def test_sender_waits_hand_computed() -> None:
    """Bursts of 1 ms, tolerance 0.1 ms. Sender A stamps 0, 1.05 and 2.2 ms: the second
    starts 0.05 ms after the first burst's end (same busy period, which ends at 2.05
    ms), the third 0.15 ms after it (a new period). The first waits 1.05 ms for the
    thread to go idle, the others leave at their own burst's end. Sender B's lone
    publish at 0 and A's at 10 ms wait for nothing; the input order is kept."""
    w = sender_waits(["A", "A", "A", "B", "A"], [0.0, 0.00105, 0.0022, 0.0, 0.01],
                     0.001, 1e-4)
    assert w.tolist() == pytest.approx([0.00105, 0.0, 0.0, 0.0, 0.0], abs=1e-15)
    # a chain of three: each waits for the last one's burst to end
    w3 = sender_waits([0, 0, 0], [0.002, 0.0, 0.001], 0.001, 0.0)
    assert w3.tolist() == pytest.approx([0.0, 0.002, 0.001], abs=1e-15)
    assert sender_waits([], [], 0.001).size == 0
