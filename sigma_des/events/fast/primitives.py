"""Primitives of the compiled message core: queueing, event slots, draws, link hops.

The handlers (:mod:`~sigma_des.events.fast.broker`,
:mod:`~sigma_des.events.fast.node`, :mod:`~sigma_des.events.fast.server`) build on
these: queueing an event (keyed ``(time, sequence)``, taken in that order by
:mod:`~sigma_des.events.fast.queue`), the event-slot free list, the
draw-table lookup and one hop over an access link (FIFO serialization, latency,
loss) — each the same floating point operations, in the same order, as
:mod:`sigma_des.net.network`. The state ``S`` is a
state tuple (:data:`~sigma_des.events.fast.layout.FIELDS`).
"""

from __future__ import annotations

from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.layout import (
    DRAW_CONST,
    DRAW_MAP,
    DRAW_TAG,
    DRAW_VAL,
    E_INDEX,
    E_KIND,
    E_SUBJ,
    E_TYPE,
    E_WHO,
    EV_BROKER,
    EV_INT,
    FPARAMS,
    FREE,
    G_END,
    G_WARMUP,
    I_EID,
    I_ERR,
    I_FREE,
    I_NEV,
    INTS,
    IPARAMS,
    LINK_BUSY,
    LINK_COUNT,
    LINK_OF,
    LINK_SPB,
    PEND_K,
    PEND_T,
    Q_FLOAT,
    Q_INT,
    Q_N,
    QF_PMIN,
    QI_PMINK,
    QI_PN,
    SLOT_BITS,
    U_OFFSET,
    WIRE_BYTES,
)
from sigma_des.events.fast.loss import forced_drop, link_loss


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
def alloc(S):  # type: ignore[no-untyped-def]
    iv = S[INTS]
    iv[I_FREE] -= 1
    return S[FREE][iv[I_FREE]]


@jit
def release(S, slot):  # type: ignore[no-untyped-def]
    iv = S[INTS]
    S[FREE][iv[I_FREE]] = slot
    iv[I_FREE] += 1


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


# ---------------------------------------------------------------- draws and links


@jit
def draw(S, src, kind, subj, index):  # type: ignore[no-untyped-def]
    c = S[DRAW_MAP][src, kind]
    if c < 0:
        return S[DRAW_CONST][src]
    tag = S[DRAW_TAG]
    r = index % tag.shape[1]
    if tag[c, r] != index:
        S[INTS][I_ERR] = 1
        return 0.0
    return S[DRAW_VAL][c, r, subj]


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
def hop(S, slot, t):  # type: ignore[no-untyped-def]
    """Network._hop for the message in ``slot`` (addressed): queue it at its arrival.

    FIFO serialization on the receiver's (down) or sender's (up) link, latency and
    loss (time-dependent: Gilbert–Elliott state, degrade windows and drop faults,
    :mod:`~sigma_des.events.fast.loss`); a lost message frees its slot.
    """
    evi = S[EV_INT]
    client = evi[slot, E_WHO]
    kind, subj, index = key_of(S, slot)
    up = 1 if evi[slot, E_TYPE] == EV_BROKER else 0
    done = count(S, client, up, S[WIRE_BYTES][kind], t)
    cls = 1 if client == S[IPARAMS][Q_N] else 0
    src = lat_source(cls, up)
    lat = draw(S, src, kind, subj, index)
    p, extra = link_loss(S, client, cls, up, t)
    lost = False
    if p > 0.0:
        lost = draw(S, U_OFFSET + src, kind, subj, index) < p
    if forced_drop(S, up, kind, subj, index):
        lost = True
    if lost:
        release(S, slot)
    else:
        push(S, done + lat + extra, slot)


@jit
def send_up(S, slot, client, kind, subject, index, t):  # type: ignore[no-untyped-def]
    """A PUBLISH (payload already in ``slot``) leaves ``client`` for the broker."""
    address(S, slot, EV_BROKER, client, kind, subject, index)
    hop(S, slot, t)
