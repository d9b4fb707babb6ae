"""De-queue measured latencies before they become the DES's per-hop draws.

Over the ``stream`` transport the DES draws each hop's latency independently and
then delivers in order per connection: a message whose draw would land it before
an earlier-sent one waits for it. A live latency already *contains* that waiting
(the shim keeps order, TCP keeps order, the receiving loop serves its backlog in
order), so resampling measured latencies and letting the DES add its in-order wait
again counts the wait twice.

The DES's connection is ``D_k = max(a_k, D_{k-1})`` in its sequence (arrival
``a_k = s_k + d_k``: send ``s``, draw ``d``; delivery ``D``), so its delivery order is its
sequence. Read backwards, a message delivered strictly after its predecessor was not
held, so its draw *is* its latency ``D_k - s_k``; a message delivered together with its
predecessor (within ``tol``: a live receiver spends a few µs per message of a backlog)
may have been held, so all that is known is ``d_k <= D_k - s_k``: a left-censored
sample. The draws' distribution is
then the Kaplan–Meier estimate for left-censored data, computed as Efron's
redistribution to the left (:func:`censored_weights`): each censored sample hands
its mass, equally, to every smaller sample (events before censored ones at a tie);
mass with no smaller sample to go to stays at its bound (an upper bound: the draw
was at most that). The censoring point ``D_{k-1} - s_k`` depends only on earlier
draws, so it is independent of ``d_k`` and the estimate is consistent.
:func:`quantiles` turns the weighted samples into the equally weighted sample file
that an empirical :class:`~sigma_des.net.latency.Dist` resamples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["HOLD_TOL", "censored_weights", "dequeued", "held", "job_services", "quantiles",
           "sender_waits"]

#: A delivery at most this long after an earlier-sent message's counts as held behind
#: it (s). Live, the loops take ~5–25 µs per message of a backlog (the gaps between
#: consecutive deliveries measured on this machine), far below the 10 ms between frames.
HOLD_TOL = 1e-4


def held(conn: ArrayLike, t_send: ArrayLike, t_recv: ArrayLike,
         tol: float = HOLD_TOL, service: float = 0.0) -> NDArray[np.bool_]:
    """Which messages may have waited behind their predecessor on their connection.

    A connection delivers in its own sequence, so its delivery order *is* its sequence
    (for a stream into one receiver that merges several senders, the broker's order,
    which send times do not give). A message delivered no later than ``tol`` after the
    previous delivery on its connection may have been held behind it.

    With ``service`` > 0 the receiver's thread spends ``service`` on each delivery
    after taking it: its busy time is replayed per connection, ``B_k = max(B_{k-1},
    r_k) + service`` over the deliveries ``r_k`` in order, and a delivery no later
    than ``B_{k-1} + tol`` may have waited for the thread (live stamps a batch of
    receipts when the thread frees, so a batch's first receipt waited for the
    previous batch's handling too). ``service = 0`` is the rule above.

    Args:
        conn: connection id of each message.
        t_send: send times (s); they order deliveries at the same instant.
        t_recv: delivery times (s).
        tol: a delivery within ``tol`` after the previous one (or after the
            receiver's thread is free again) counts as held.
        service: the receiver's CPU per delivery (s).

    Returns:
        ``held[k]`` in the input order (the first delivery of a connection is never held).
    """
    c = np.asarray(conn)
    s = np.asarray(t_send, dtype=np.float64)
    d = np.asarray(t_recv, dtype=np.float64)
    out = np.zeros(s.size, dtype=bool)
    if s.size == 0:
        return out
    order = np.lexsort((s, d, c))  # by connection, then delivery (then send) time
    cs, ds = c[order], d[order]
    same = np.zeros(s.size, dtype=bool)
    same[1:] = cs[1:] == cs[:-1]
    if service > 0.0:
        out[order] = _busy_held(same, ds, tol, service)
        return out
    gap = np.empty(s.size)
    gap[0] = np.inf
    gap[1:] = ds[1:] - ds[:-1]
    out[order] = same & (gap <= tol)
    return out


def _busy_held(same: NDArray[np.bool_], ds: NDArray[np.float64], tol: float,
               service: float) -> NDArray[np.bool_]:
    """:func:`held` with a receiver thread (deliveries sorted by connection, then time)."""
    out = np.zeros(ds.size, dtype=bool)
    busy = -np.inf
    for k in range(ds.size):
        r = float(ds[k])
        if not same[k]:
            busy = -np.inf
        out[k] = r <= busy + tol
        busy = (busy if busy > r else r) + service
    return out


def sender_waits(sender: ArrayLike, t_send: ArrayLike, length: float,
                 tol: float = HOLD_TOL) -> NDArray[np.float64]:
    """How long each message waited, after its publish burst, for its sender's thread
    to go idle (when the DES lets it leave: docs/concepts/deployment.md).

    Each sender's publishes are replayed in time order: a publish stamped at ``t`` (its
    handler's start) holds the thread for ``length``; the next one stamped within
    ``tol`` of that burst's end belongs to the same busy period. Every message of a
    busy period leaves at its end, so its wait is the period's end less its own
    burst's end. Receives also keep a thread busy; the rows do not time them, so they
    are not counted (the estimate is a lower bound).

    Args:
        sender: sender id of each message.
        t_send: publish stamps (s).
        length: one publish burst (s, >= 0).
        tol: largest gap that still continues a busy period (s).

    Returns:
        The waits (s, >= 0), in the input order.
    """
    c = np.asarray(sender)
    t = np.asarray(t_send, dtype=np.float64)
    out = np.zeros(t.size)
    if t.size == 0:
        return out
    order = np.lexsort((t, c))
    cs, ts = c[order], t[order]
    start = np.ones(t.size, dtype=bool)  # a busy period starts here
    start[1:] = (cs[1:] != cs[:-1]) | (ts[1:] > ts[:-1] + length + tol)
    period = np.cumsum(start) - 1
    last = np.zeros(int(period[-1]) + 1)
    np.maximum.at(last, period, ts)
    out[order] = last[period] - ts
    return out


def censored_weights(x: ArrayLike, censored: ArrayLike) -> tuple[NDArray[np.float64],
                                                                  NDArray[np.float64]]:
    """Kaplan–Meier masses of left-censored samples (Efron's redistribution to the left).

    Args:
        x: sample values (an exact value, or an upper bound where ``censored``).
        censored: True where only ``value <= x`` is known.

    Returns:
        ``(values, weights)``: the values sorted ascending (events before censored
        ones at a tie) and their masses, summing to 1. A censored sample keeps mass
        only if no smaller sample can take it.
    """
    xv = np.asarray(x, dtype=np.float64)
    cv = np.asarray(censored, dtype=bool)
    n = xv.size
    if n == 0:
        return xv.copy(), np.zeros(0)
    order = np.lexsort((cv, xv))
    xs, cs = xv[order], cv[order]
    w = np.full(n, 1.0 / n)
    # from the largest down: a censored sample spreads its (current) mass equally over
    # the samples left of it; a running "share per sample" keeps this O(n)
    share = 0.0  # mass handed to each sample left of the current position
    for i in range(n - 1, -1, -1):
        w[i] += share
        if cs[i] and i > 0:
            share += w[i] / i
            w[i] = 0.0
    return xs, w


def quantiles(values: ArrayLike, weights: ArrayLike, m: int) -> NDArray[np.float64]:
    """``m`` equally weighted samples of a weighted discrete distribution: its quantiles
    at ``(i + 1/2) / m`` (what an empirical Dist file holds).

    Args:
        values: support, ascending.
        weights: masses (summing to 1).
        m: number of samples to write, >= 1.
    """
    v = np.asarray(values, dtype=np.float64)
    cdf = np.cumsum(np.asarray(weights, dtype=np.float64))
    cdf /= cdf[-1]
    u = (np.arange(m) + 0.5) / m
    return v[np.minimum(np.searchsorted(cdf, u, side="left"), v.size - 1)]


def dequeued(conn: ArrayLike, t_send: ArrayLike, t_recv: ArrayLike,
             tol: float = HOLD_TOL) -> tuple[NDArray[np.float64], float]:
    """The DES draws implied by in-order latencies: ``n`` equally weighted samples of the
    Kaplan–Meier estimate (see the module doc), and the share of held messages.

    Args:
        conn: connection id per message.
        t_send: send times (s).
        t_recv: delivery times (s).
        tol: see :func:`held`.

    Returns:
        The samples (ascending, one per message) and the fraction of held messages.
    """
    s = np.asarray(t_send, dtype=np.float64)
    lat = np.asarray(t_recv, dtype=np.float64) - s
    h = held(conn, s, t_recv, tol)
    xs, w = censored_weights(lat, h)
    return quantiles(xs, w, lat.size), float(h.mean()) if h.size else 0.0


def job_services(host: ArrayLike, node: ArrayLike, t_req: ArrayLike, t_done: ArrayLike,
                 cores: int) -> NDArray[np.float64]:
    """Service times of jobs that queued FCFS for ``cores`` cores per host.

    The DES (and the live host) runs each node's step on ``cores`` FCFS cores of its
    host; a job is requested at its trigger's receipt or, if the node was still busy,
    when its previous job finished. Publish minus trigger receipt therefore holds
    the wait for a core, which the DES adds again. Replayed in request order, job
    ``k`` starts at ``max(request, earliest free core)`` and occupies that core until
    it finished (its publish), so its service is ``done - start``: the FCFS analogue
    of :func:`held` for jobs.

    A node's previous job is looked for among its own host's jobs only, so a caller may
    key ``host`` by run (``method/host``): each method's times start at 0, and a node's
    job in another method is not its previous one.

    Args:
        host: host of each job (one replay per distinct value).
        node: node of each job.
        t_req: when its trigger arrived (s).
        t_done: when it finished (its state was published, s).
        cores: cores per host, >= 1.

    Returns:
        The service time of each job (s, in the input order; >= 0).
    """
    import heapq

    h = np.asarray(host)
    nd = np.asarray(node)
    done = np.asarray(t_done, dtype=np.float64)
    out = np.zeros(done.size)
    for hh in np.unique(h):
        idx = np.flatnonzero(h == hh)
        req = np.asarray(t_req, dtype=np.float64)[idx]  # a copy: fancy indexing
        hn, hd = nd[idx], done[idx]
        # a busy node's next job is requested no earlier than its previous one finished
        for n in np.unique(hn):
            mine = np.flatnonzero(hn == n)
            mine = mine[np.argsort(hd[mine], kind="stable")]
            req[mine[1:]] = np.maximum(req[mine[1:]], hd[mine[:-1]])
        free = [-np.inf] * cores
        for j in np.lexsort((hn, req)).tolist():
            start = max(float(req[j]), heapq.heappop(free))
            out[idx[j]] = max(hd[j] - start, 0.0)
            heapq.heappush(free, max(float(hd[j]), start))
    return out
