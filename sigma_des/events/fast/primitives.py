"""Primitives of the compiled message core: queueing, event slots, draws, link hops.

The handlers (:mod:`~sigma_des.events.fast.broker`,
:mod:`~sigma_des.events.fast.node`, :mod:`~sigma_des.events.fast.server`) build on
these: queueing an event (keyed ``(time, sequence)``, taken in that order by
:mod:`~sigma_des.events.fast.queue`), the event-slot free list, the
draw-table lookup and a packet's serialization, latency and loss on an access link
(the hop that queues its arrival is :func:`~sigma_des.events.fast.channel.hop`) — each
the same floating point operations, in the same order, as
:mod:`sigma_des.net.network`. The state ``S`` is a
state tuple (:data:`~sigma_des.events.fast.layout.FIELDS`).
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    E_ATT,
    E_INDEX,
    E_KIND,
    E_PAY,
    E_SUBJ,
    E_TYPE,
    E_WHO,
    G_END,
    G_WARMUP,
    I_EID,
    I_ERR,
    I_FREE,
    I_NEV,
    I_PFREE,
    N_KINDS,
    Q_N,
    QF_PMIN,
    QI_PMINK,
    QI_PN,
    SLOT_BITS,
    T_RETRIES,
    T_XROWS,
    U_OFFSET,
)
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.layout import (
    ACK_MAP,
    ACK_TAG,
    ACK_VAL,
    DRAW_CONST,
    DRAW_MAP,
    DRAW_TAG,
    DRAW_VAL,
    ERR_RANGE,
    EV_FLOAT,
    EV_INT,
    EV_INT_MAX,
    FPARAMS,
    FREE,
    INTS,
    IPARAMS,
    LINK_BUSY,
    LINK_COUNT,
    LINK_OF,
    LINK_SPB,
    PEND_K,
    PEND_T,
    POOL,
    POOL_FREE,
    Q_FLOAT,
    Q_INT,
    TR_PARAMS,
    X_CONST,
    X_MAP,
    X_TAG,
    X_VAL,
)
from sigma_des.events.fast.loss import forced_drop, link_loss
from sigma_des.events.fast.prefetch import prefetch


@jit
def lat_source(cls: int, up: int) -> int:
    """Latency source of link class ``cls`` (0 host, 1 server) and direction ``up``."""
    return 2 * (1 - cls) + (1 - up)


@jit
def in_window(S, t):  # type: ignore[no-untyped-def]
    """Whether ``t`` lies in the measurement window ``[warmup, end)``."""
    g = S[FPARAMS]
    return g[G_WARMUP] <= t and t < g[G_END]


# ---------------------------------------------------------------- queueing and slots


@jit
def precedes(t1, k1, t2, k2):  # type: ignore[no-untyped-def]
    """Whether event ``(t1, k1)`` comes first: earlier, or as early and sooner made."""
    return t1 < t2 or (t1 == t2 and k1 < k2)


@jit
def push(S, t, slot):  # type: ignore[no-untyped-def]
    """Queue an event at ``t`` for ``slot``; its sequence number is the creation order.

    The event joins the pending buffer of :mod:`~sigma_des.events.fast.queue`
    (sealed into a sorted run before it could be due); its minimum is kept.
    """
    iv = S[INTS]
    e = iv[I_EID]
    iv[I_EID] = e + 1
    iv[I_NEV] += 1
    key = (e << SLOT_BITS) | slot  # sequence number first: it alone orders equal times
    qi = S[Q_INT]
    m = qi[QI_PN]
    S[PEND_T][m] = t
    S[PEND_K][m] = key
    qi[QI_PN] = m + 1
    qf = S[Q_FLOAT]
    if m == 0 or t < qf[QF_PMIN]:  # a later key at an equal time never comes first
        qf[QF_PMIN] = t
        qi[QI_PMINK] = key


@jit
def push_key(S, t, key):  # type: ignore[no-untyped-def]
    """Queue an event at ``t`` under a ``key`` it already has (a fan-out's delivery, whose
    sequence number the broker took: :mod:`~sigma_des.events.fast.fanout`).

    The key may be older than pending ones, so the pending minimum is kept by the whole
    ``(time, key)`` comparison; the sealing sorts by it anyway.
    """
    qi = S[Q_INT]
    m = qi[QI_PN]
    S[PEND_T][m] = t
    S[PEND_K][m] = key
    qi[QI_PN] = m + 1
    qf = S[Q_FLOAT]
    if m == 0 or precedes(t, key, qf[QF_PMIN], qi[QI_PMINK]):
        qf[QF_PMIN] = t
        qi[QI_PMINK] = key


#: Allocations ahead whose rows :func:`alloc` and :func:`give_payload` ask the cache for:
#: a broadcast takes a slot per subscriber in a row, most of them long unused.
AHEAD = 4


@jit
def alloc(S):  # type: ignore[no-untyped-def]
    """A free event slot (it carries no payload: :func:`release` took its row back)."""
    iv = S[INTS]
    top = iv[I_FREE] - 1
    iv[I_FREE] = top
    free = S[FREE]
    if top >= AHEAD:
        prefetch(S[EV_INT], free[top - AHEAD])
        prefetch(S[EV_FLOAT], free[top - AHEAD])
    return free[top]


@jit
def release(S, slot):  # type: ignore[no-untyped-def]
    """Free ``slot`` and its payload row, if it has one."""
    iv = S[INTS]
    evi = S[EV_INT]
    r = evi[slot, E_PAY] - 1
    if r >= 0:
        S[POOL_FREE][iv[I_PFREE]] = r
        iv[I_PFREE] += 1
        evi[slot, E_PAY] = 0
    S[FREE][iv[I_FREE]] = slot
    iv[I_FREE] += 1


# A payload (a state's observation, a command's row) is a row of the pool, allocated
# with the slot that carries it and freed with it: a trigger or re-request, half of a
# saturated broker's backlog, carries none.
# The pool has as many rows as the loop may need before Python grows it (loop._limits).


@jit
def give_payload(S, slot):  # type: ignore[no-untyped-def]
    """A pool row for ``slot``'s payload (``slot`` has none yet): its index."""
    iv = S[INTS]
    top = iv[I_PFREE] - 1
    iv[I_PFREE] = top
    pf = S[POOL_FREE]
    if top >= AHEAD:
        prefetch(S[POOL], pf[top - AHEAD])
    r = pf[top]
    S[EV_INT][slot, E_PAY] = r + 1  # < MAX_SLOTS: the pool grows no further (growth)
    return r


@jit
def payload(S, slot):  # type: ignore[no-untyped-def]
    """The pool row holding ``slot``'s payload."""
    return S[EV_INT][slot, E_PAY] - 1


@jit
def copy_payload(S, src, dst):  # type: ignore[no-untyped-def]
    """Give ``dst`` (no payload yet) a copy of ``src``'s payload, if it carries one."""
    r = S[EV_INT][src, E_PAY] - 1
    S[EV_INT][dst, E_PAY] = 0
    if r < 0:
        return
    pool = S[POOL]
    d = give_payload(S, dst)
    for j in range(pool.shape[1]):
        pool[d, j] = pool[r, j]


@jit
def key_of(S, slot):  # type: ignore[no-untyped-def]
    """The message key ``(kind, subject, index)`` of the event in ``slot``."""
    evi = S[EV_INT]
    return evi[slot, E_KIND], evi[slot, E_SUBJ], evi[slot, E_INDEX]


@jit
def address(S, slot, typ, who, kind, subject, index):  # type: ignore[no-untyped-def]
    """Write an event's type, receiver and message key into ``slot``."""
    evi = S[EV_INT]
    evi[slot, E_TYPE] = typ
    evi[slot, E_WHO] = who
    evi[slot, E_KIND] = kind
    evi[slot, E_SUBJ] = subject
    evi[slot, E_INDEX] = index
    evi[slot, E_ATT] = 0  # a first transmission (resends set their attempt)


@jit
def put_int(S, slot, col, value):  # type: ignore[no-untyped-def]
    """Store ``value`` in int column ``col`` of ``slot``, if the int32 column holds it.

    For values the loop makes that have no bound of their own (an HLC counter, a
    stream sequence number); a value beyond the column is not stored (it would wrap)
    but is an error, ``ERR_RANGE``: the driver runs the whole run per message.
    """
    if value > EV_INT_MAX or value < -EV_INT_MAX - 1:
        S[INTS][I_ERR] = ERR_RANGE
        return
    S[EV_INT][slot, col] = value


# ---------------------------------------------------------------- draws and links


@jit
def row_of(index, rows):  # type: ignore[no-untyped-def]
    """``index % rows`` (Python's floor modulo), by a mask when ``rows`` is a power of two.

    Tables have ``history_frames`` rows (512 by default); an integer division costs
    tens of cycles, several times per message event, and for a power of two the mask
    gives the floor modulo of every integer, negative ones included (two's complement).
    """
    if rows & (rows - 1) == 0:
        return index & (rows - 1)
    return index % rows


@jit
def _tabled(S, tag, val, c, r, key, subj):  # type: ignore[no-untyped-def]
    """Value ``subj`` of row ``r`` of table ``c`` if the row holds ``key``, else an error
    (the row was never filled, or was refilled for a newer key)."""
    if tag[c, r] != key:
        S[INTS][I_ERR] = 1
        return 0.0
    return val[c, r, subj]


@jit
def draw(S, src, kind, subj, index):  # type: ignore[no-untyped-def]
    c = S[DRAW_MAP][src, kind]
    if c < 0:
        return S[DRAW_CONST][src]
    tag = S[DRAW_TAG]
    return _tabled(S, tag, S[DRAW_VAL], c, row_of(index, tag.shape[1]), index, subj)


@jit
def count(S, client, up, nbytes, t):  # type: ignore[no-untyped-def]
    """Network._count: FIFO serialization on the client's link, counted in the window.

    Returns:
        The time the last bit leaves.
    """
    link = S[LINK_OF][client]
    lb = S[LINK_BUSY]
    busy = lb[up, link]
    done = (t if t > busy else busy) + nbytes * S[LINK_SPB][up, link]
    lb[up, link] = done
    if in_window(S, t):
        S[LINK_COUNT][up, 0, link] += nbytes
        S[LINK_COUNT][up, 1, link] += 1
    return done


@jit
def attempt_key(S, index, attempt):  # type: ignore[no-untyped-def]
    """The key of ``(index, attempt)`` in the attempt tables, and its row."""
    key = index * (S[TR_PARAMS][T_RETRIES] + 1) + attempt
    return key, row_of(key, S[TR_PARAMS][T_XROWS])


@jit
def _constant(S, src, c):  # type: ignore[no-untyped-def]
    """A constant source's value (``c == -1``); an unregistered one (-2) is an error."""
    if c == -1:
        return S[X_CONST][src]
    S[INTS][I_ERR] = 1
    return 0.0


@jit
def draw_at(S, src, kind, subj, index, attempt, ack):  # type: ignore[no-untyped-def]
    """The draw of ``(kind [+ ACK], subj, index, attempt)`` from source ``src``.

    Attempt 0 of a PUBLISH is in the main tables (:func:`draw`), attempt 0 of its
    PUBACK (``ack``) in the PUBACK tables, later attempts in the attempt tables
    (filled on demand: :func:`sigma_des.events.fast.transport.missing`).
    """
    if attempt == 0:
        if not ack:
            return draw(S, src, kind, subj, index)
        c = S[ACK_MAP][src, kind]
        if c < 0:
            return _constant(S, src, c)
        tag = S[ACK_TAG]
        return _tabled(S, tag, S[ACK_VAL], c, row_of(index, tag.shape[1]), index, subj)
    c = S[X_MAP][src, kind + N_KINDS if ack else kind]
    if c < 0:
        return _constant(S, src, c)
    key, r = attempt_key(S, index, attempt)
    return _tabled(S, S[X_TAG], S[X_VAL], c, r, key, subj)


@jit
def fly(S, client, up, kind, subj, index, attempt, ack, done, t):  # type: ignore[no-untyped-def]
    """Latency and loss of a packet sent at ``t`` whose last bit left ``client``'s link
    at ``done`` (Links.hop after the serialization; ``ack``: a PUBACK's draws).

    Returns:
        (arrival time at the far end, lost?)
    """
    cls = 1 if client == S[IPARAMS][Q_N] else 0
    src = lat_source(cls, up)
    lat = draw_at(S, src, kind, subj, index, attempt, ack)
    p, extra = link_loss(S, client, cls, up, t)
    lost = False
    if p > 0.0:
        lost = draw_at(S, U_OFFSET + src, kind, subj, index, attempt, ack) < p
    # a drop fault loses a message's first transmission (a PUBACK's key is kind + ACK)
    if attempt == 0 and not ack and forced_drop(S, up, kind, subj, index):
        lost = True
    return done + lat + extra, lost


@jit
def copy_rows(values, tags, tables, widths, block, j, row, index):  # type: ignore[no-untyped-def]
    """Row ``row`` of each table ``tables[t]``: the head ``widths[t]`` of ``block[t, j]``,
    tagged ``index``."""
    for t in range(tables.shape[0]):
        c = tables[t]
        for x in range(widths[t]):
            values[c, row, x] = block[t, j, x]
        tags[c, row] = index
