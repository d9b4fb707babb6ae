"""The compiled core's event queue: a k-way merge of sorted runs (docs/concepts/engines.md).

The specification orders events totally by ``(time, sequence)``, the sequence
being the creation (push) order. :func:`~sigma_des.events.fast.primitives.push`
appends each new event to the *pending* buffer, which is therefore in sequence
order, and tracks the pending minimum in O(1). Before an event is taken
(:func:`peek`), the pending buffer is *sealed* if its minimum would come first:
sorted by ``(time, sequence)`` (a natural merge sort, linear on the nearly sorted
batches of a broadcast) into one *run*, an array segment of the *arena*. The
heap holds only the heads of runs; the *current* run, whose head is the earliest
event, stays out of it and is consumed without any heap operation while its next
element precedes both the heap's top and the pending minimum. Every comparison is
the specification's ``(time, sequence)`` comparison on unique keys, so events come
out in exactly the order of one heap of all events.

Capacity: every queued event holds its own event slot, so the pending buffer
(``cap``) and the live part of the arena never exceed the event table; the arena
(``arena`` = :data:`ARENA` x ``cap`` rows) is compacted in place when its top is
reached, and grows with the event table (``CompiledCore.ensure_space``). The run
table (each run's position and end) has ``cap`` rows: live runs and pending events
each hold an event slot, so after a compaction there is always a free run id.
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    QF_PMIN,
    QI_ATOP,
    QI_CUR,
    QI_HAS,
    QI_HEAP,
    QI_NRUN,
    QI_PMINK,
    QI_PN,
    SLOT_MASK,
)
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.layout import (
    BOUNDS,
    HEAP_K,
    HEAP_R,
    HEAP_T,
    PEND_K,
    PEND_T,
    Q_FLOAT,
    Q_INT,
    RUN_END,
    RUN_FWD,
    RUN_K,
    RUN_POS,
    RUN_T,
)
from sigma_des.events.fast.primitives import precedes, push_key

__all__ = ["ARENA", "back_in_place", "first", "own_run", "peek", "replace_top", "take", "view"]

#: Size of the run arena in event-table rows (a compaction moves at most ``cap`` live
#: events, at most once per ``(ARENA - 1) x cap`` sealed ones). 1.25, not 2 or 4: the
#: arena's times and keys are 16 B a row, and a saturated broker's backlog can hold 10^6
#: slots (12 MB less at 10^6 slots than an arena of 2; compactions
#: 4x as often, a move of the live runs each).
ARENA = 1.25

# ---------------------------------------------------------------- the queue's arrays

# positions in the queue view Q (:func:`view`): the queue's arrays only, so a call
# passes ~13 array descriptors, not the whole state tuple (numba passes a tuple by
# value: ~3 kB of descriptors for ``S``, copied on every call that is not inlined)
V_INT, V_FLOAT, V_HT, V_HK, V_HR, V_AT, V_AK, V_POS, V_END, V_PT, V_PK, V_B, V_FWD = range(13)


@jit
def view(S):  # type: ignore[no-untyped-def]
    """The queue's arrays of state ``S``, in the order of the ``V_*`` positions."""
    return (S[Q_INT], S[Q_FLOAT], S[HEAP_T], S[HEAP_K], S[HEAP_R], S[RUN_T], S[RUN_K],
            S[RUN_POS], S[RUN_END], S[PEND_T], S[PEND_K], S[BOUNDS], S[RUN_FWD])


# ---------------------------------------------------------------- heap of run heads


@jit
def _hput(ht, hk, hr, i, t, k, r):  # type: ignore[no-untyped-def]
    ht[i] = t
    hk[i] = k
    hr[i] = r


@jit
def _sift_up(ht, hk, hr, i, t, k, r):  # type: ignore[no-untyped-def]
    while i > 0:
        p = (i - 1) >> 1
        if not precedes(t, k, ht[p], hk[p]):
            break
        _hput(ht, hk, hr, i, ht[p], hk[p], hr[p])
        i = p
    _hput(ht, hk, hr, i, t, k, r)


@jit
def replace_top(ht, hk, hr, n, t, k, r):  # type: ignore[no-untyped-def]
    """Put head ``(t, k)`` of run ``r`` in the root's place in the ``n``-entry heap."""
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and precedes(ht[c + 1], hk[c + 1], ht[c], hk[c]):
            c += 1
        if not precedes(ht[c], hk[c], t, k):
            break
        _hput(ht, hk, hr, i, ht[c], hk[c], hr[c])
        i = c
    _hput(ht, hk, hr, i, t, k, r)


# ---------------------------------------------------------------- sealing


@jit
def _merge(xt, xk, xo, yt, yk, yo, lo, mid, hi):  # type: ignore[no-untyped-def]
    """Merge sorted ``x[xo+lo:xo+mid]`` and ``x[xo+mid:xo+hi]`` into ``y[yo+lo:yo+hi]``."""
    i = lo
    j = mid
    o = yo + lo
    while i < mid and j < hi:
        if precedes(xt[xo + j], xk[xo + j], xt[xo + i], xk[xo + i]):
            yt[o] = xt[xo + j]
            yk[o] = xk[xo + j]
            j += 1
        else:
            yt[o] = xt[xo + i]
            yk[o] = xk[xo + i]
            i += 1
        o += 1
    while i < mid:
        yt[o] = xt[xo + i]
        yk[o] = xk[xo + i]
        i += 1
        o += 1
    while j < hi:
        yt[o] = xt[xo + j]
        yk[o] = xk[xo + j]
        j += 1
        o += 1


@jit
def _sort_pending(Q, m, a):  # type: ignore[no-untyped-def]
    """Sort the ``m`` pending events by ``(t, key)`` into the arena at ``a``.

    A natural merge sort: the ascending stretches of the pending buffer are merged
    pairwise, pass after pass, between the pending buffer and the arena segment.
    """
    pt = Q[V_PT]
    pk = Q[V_PK]
    at = Q[V_AT]
    ak = Q[V_AK]
    b = Q[V_B]
    nr = 0
    b[0] = 0
    for i in range(1, m):
        if precedes(pt[i], pk[i], pt[i - 1], pk[i - 1]):
            nr += 1
            b[nr] = i
    nr += 1
    b[nr] = m
    in_pending = True
    while nr > 1:
        j = 0
        for r in range(0, nr, 2):
            lo = b[r]
            hi = b[r + 2] if r + 2 <= nr else b[r + 1]
            mid = b[r + 1] if r + 1 < nr else hi
            if in_pending:
                _merge(pt, pk, 0, at, ak, a, lo, mid, hi)
            else:
                _merge(at, ak, a, pt, pk, 0, lo, mid, hi)
            b[j] = lo
            j += 1
        b[j] = m
        nr = j
        in_pending = not in_pending
    if in_pending:
        for i in range(m):
            at[a + i] = pt[i]
            ak[a + i] = pk[i]


@jit
def _compact(Q):  # type: ignore[no-untyped-def]
    """Move the live runs to the front of the arena, renumbering them in order.

    Runs are numbered in the order they were sealed, which is their order in the
    arena, so one pass moves every live segment down; the heap's run ids (and the
    current run's) follow the renumbering.
    """
    qi = Q[V_INT]
    at = Q[V_AT]
    ak = Q[V_AK]
    pos = Q[V_POS]
    end = Q[V_END]
    fwd = Q[V_FWD]
    dst = 0
    j = 0
    for r in range(qi[QI_NRUN]):
        p = pos[r]
        e = end[r]
        fwd[r] = j
        if p == e:
            continue
        pos[j] = dst
        for i in range(p, e):
            at[dst] = at[i]
            ak[dst] = ak[i]
            dst += 1
        end[j] = dst
        j += 1
    qi[QI_NRUN] = j
    qi[QI_ATOP] = dst
    hr = Q[V_HR]
    for h in range(qi[QI_HEAP]):
        hr[h] = fwd[hr[h]]
    if qi[QI_HAS]:
        qi[QI_CUR] = fwd[qi[QI_CUR]]


@jit
def _seal(Q):  # type: ignore[no-untyped-def]
    """Sort the pending events into a new run; return its id."""
    qi = Q[V_INT]
    m = qi[QI_PN]
    # live runs + pending events <= cap (each holds an event slot), so after a
    # compaction both the arena and the run table (cap rows) have room for this run
    if qi[QI_ATOP] + m > Q[V_AT].shape[0] or qi[QI_NRUN] >= Q[V_POS].shape[0]:
        _compact(Q)
    a = qi[QI_ATOP]
    _sort_pending(Q, m, a)
    r = qi[QI_NRUN]
    qi[QI_NRUN] = r + 1
    Q[V_POS][r] = a
    Q[V_END][r] = a + m
    qi[QI_ATOP] = a + m
    qi[QI_PN] = 0
    return r


@jit
def back_in_place(S, c, p, t, k):  # type: ignore[no-untyped-def]
    """Put ``(t, k)`` back at arena row ``p``, the head of run ``c`` just taken, when the
    run has no next entry or ``(t, k)`` precedes it (the run stays sorted); whether it
    did. A batch's next element (fan-out, channel) goes back so without a queue push."""
    at = S[RUN_T]
    ak = S[RUN_K]
    if p + 1 == S[RUN_END][c] or precedes(t, k, at[p + 1], ak[p + 1]):
        at[p] = t
        ak[p] = k
        S[RUN_POS][c] = p
        S[Q_INT][QI_HAS] = 1
        return True
    return False


@jit
def own_run(S, t, k):  # type: ignore[no-untyped-def]
    """Queue ``(t, k)`` as a run of its own, its head straight into the heap.

    For a batch's token (:mod:`~sigma_des.events.fast.channel`): a one-row run goes back
    in place whenever its token is taken and re-queued under its next element's key,
    whatever falls between, so the batch never passes through the pending buffer again.
    Never compacts (a handler may call it while the loop holds a run position): without
    room at the arena's top or in the run table the event joins the pending buffer.

    Returns:
        Whether it got a run of its own.
    """
    qi = S[Q_INT]
    a = qi[QI_ATOP]
    r = qi[QI_NRUN]
    if a >= S[RUN_T].shape[0] or r >= S[RUN_POS].shape[0]:
        push_key(S, t, k)
        return False
    S[RUN_T][a] = t
    S[RUN_K][a] = k
    S[RUN_POS][r] = a
    S[RUN_END][r] = a + 1
    qi[QI_ATOP] = a + 1
    qi[QI_NRUN] = r + 1
    n = qi[QI_HEAP]
    qi[QI_HEAP] = n + 1
    _sift_up(S[HEAP_T], S[HEAP_K], S[HEAP_R], n, t, k, r)
    return True


# ---------------------------------------------------------------- taking events


@jit
def first(Q):  # type: ignore[no-untyped-def]
    """Make the earliest queued event the head of the current run.

    Args:
        Q: the queue's arrays (:func:`view`).

    Returns:
        Its time; the queue is empty if ``Q[V_INT][QI_HAS]`` is 0 afterwards.
    """
    qi = Q[V_INT]
    at = Q[V_AT]
    ak = Q[V_AK]
    ht = Q[V_HT]
    hk = Q[V_HK]
    hr = Q[V_HR]
    has = qi[QI_HAS]
    c = qi[QI_CUR]
    ct = 0.0
    ck = 0
    if has:
        p = Q[V_POS][c]
        ct = at[p]
        ck = ak[p]
    n = qi[QI_HEAP]
    if n > 0 and (not has or precedes(ht[0], hk[0], ct, ck)):
        top = hr[0]
        tt = ht[0]
        tk = hk[0]
        if has:  # the current run goes back into the heap in the top's place
            replace_top(ht, hk, hr, n, ct, ck, c)
        else:
            qi[QI_HEAP] = n - 1
            if n > 1:
                replace_top(ht, hk, hr, n - 1, ht[n - 1], hk[n - 1], hr[n - 1])
        c = top
        ct = tt
        ck = tk
        has = 1
    if qi[QI_PN] > 0:
        pt = Q[V_FLOAT][QF_PMIN]
        pk = qi[QI_PMINK]
        if not has or precedes(pt, pk, ct, ck):
            if has:
                n = qi[QI_HEAP]
                qi[QI_HEAP] = n + 1
                _sift_up(ht, hk, hr, n, ct, ck, c)
            qi[QI_HAS] = 0  # the sealing may renumber runs: only heap ids follow
            c = _seal(Q)
            ct = pt
            has = 1
    qi[QI_HAS] = has
    qi[QI_CUR] = c
    return ct


@jit
def peek(S):  # type: ignore[no-untyped-def]
    """:func:`first` on the queue of state ``S``."""
    return first(view(S))


@jit
def take(S):  # type: ignore[no-untyped-def]
    """Remove the head of the current run (after :func:`peek`); return its event slot.

    The event loop does this (and the check that no :func:`first` is needed) inline.
    """
    qi = S[Q_INT]
    c = qi[QI_CUR]
    pos = S[RUN_POS]
    p = pos[c]
    pos[c] = p + 1
    if p + 1 == S[RUN_END][c]:
        qi[QI_HAS] = 0
    return S[RUN_K][p] & SLOT_MASK
