"""Fan-out batches: a broadcast's deliveries as few queue entries (docs/concepts/engines.md).

A broadcast (a trigger) leaves the broker as one delivery per subscriber, their
departures one cumulative sum of delivery services (the broker's FIFO); without
hold-back on the links each arrives at its departure plus serialization plus latency.
In the specification every delivery is an event keyed ``(arrival, sequence)``. Here a
broadcast whose arrivals do not decrease in the broker's delivery order is one *batch*:
one event slot carrying the message, and the arrivals, sequence numbers and subscribers
in a ring of elements (``bat_t``, ``bat_k``, ``bat_w``). The sequence numbers are taken
as the specification's pushes take them (one per delivery not lost, in delivery order);
arrival and sequence both increase, so the head is the earliest element. It is queued under
its head's key; when the loop takes it, the head delivery runs (the same handler on the
same fields: :func:`head`), and the batch goes back under its next element's key
(:func:`requeue`): in place in its run when that key still precedes the run's next
entry (nothing fell between), else into the pending buffer. The queue so yields the
specification's events in the specification's order: results are bit-identical.

The broker fans out per message where batching does not apply: a CPU stage at the
clients (receive bursts, host clients), QoS 1 over datagram or a stream with hold-back
(:func:`applies`), a broadcast carrying a payload, or a ring without room for one more
broadcast (:func:`fits`); a broadcast whose arrivals are out of order (random latency,
a degraded link, hosts' links slower than the broker) is queued as one plain delivery
event per delivery, as batches of its in-order stretches would interleave (each
element going back through the pending buffer, measured slower than per message). A
lost delivery takes no sequence number and no element, as in the specification.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import NDArray

from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.codes import (
    CP_NSUB,
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_NEXT,
    E_PAY,
    E_SEQ,
    E_SUBJ,
    E_WHO,
    EF_TDEP,
    EV_BATCH,
    EV_CLIENT,
    I_BELEM,
    I_BHEAD,
    I_BPUSH,
    I_BREIN,
    I_BSING,
    I_BTAIL,
    I_BUSED,
    I_EID,
    I_NEV,
    SLOT_BITS,
    SVC_DEL,
)
from sigma_des.events.fast.layout import (
    BAT_K,
    BAT_T,
    BAT_W,
    BCAST,
    CPU_IP,
    EV_FLOAT,
    EV_INT,
    INTS,
    WIRE_BYTES,
)
from sigma_des.events.fast.primitives import (
    address,
    alloc,
    count,
    draw_at,
    fly,
    jit,
    push_key,
)
from sigma_des.events.fast.queue import back_in_place

__all__ = ["ENABLED", "applies", "counts", "fan_out", "fits", "head", "one_event_hops",
           "requeue"]

#: Broadcasts fan out in batches where they can (results are bit-identical either way;
#: False: one queue entry per delivery, as in the specification). Read when a run's
#: core is built.
ENABLED = True


def one_event_hops(S: tuple[NDArray[Any], ...]) -> bool:
    """Whether a hop of the run is one event: no CPU stage at the clients, no QoS 1 over
    datagram, no stream with hold-back (what batching, here and in channels, needs)."""
    tp, cp = S[L.TR_PARAMS], S[L.CPU_IP]
    return not (cp[CO.CP_APP] or tp[CO.T_QOS1D] or tp[CO.T_STREAM] or tp[CO.T_STREAM + 1])


def applies(S: tuple[NDArray[Any], ...]) -> bool:
    """Whether the run's broadcasts fan out in batches: :data:`ENABLED` and
    :func:`one_event_hops`."""
    return ENABLED and one_event_hops(S)


def counts(S: tuple[NDArray[Any], ...]) -> dict[str, int]:
    """The run's fan-out counters: whether it batches (``on``), deliveries run from
    batches (``batched``), batches queued (``batches``), batches queued again
    (``requeued``), deliveries queued one by one (``single``: out-of-order broadcasts)."""
    iv = S[L.INTS]
    return {"on": int(S[L.IPARAMS][CO.Q_FAN]), "batched": int(iv[CO.I_BELEM]),
            "batches": int(iv[CO.I_BPUSH]), "requeued": int(iv[CO.I_BREIN]),
            "single": int(iv[CO.I_BSING])}


@jit
def fits(S, src, nsub):  # type: ignore[no-untyped-def]
    """Whether the broadcast in slot ``src`` (``nsub`` subscribers) can fan out in batches
    now: it carries no payload and the ring has room for every delivery."""
    return S[EV_INT][src, E_PAY] == 0 and S[BAT_T].shape[0] - S[INTS][I_BUSED] >= nsub


@jit
def _consume(S, i):  # type: ignore[no-untyped-def]
    """Element ``i`` is delivered: mark it; free the delivered elements at the ring's tail."""
    bk = S[BAT_K]
    bk[i] = -1
    iv = S[INTS]
    r = bk.shape[0]
    t = iv[I_BTAIL]
    u = iv[I_BUSED]
    while u > 0 and bk[t] < 0:
        t += 1
        if t == r:
            t = 0
        u -= 1
    iv[I_BTAIL] = t
    iv[I_BUSED] = u


@jit
def _slot(S, src, typ, who, d):  # type: ignore[no-untyped-def]
    """A delivery's event slot as the broker's ``_deliver`` fills it (``src`` carries no
    payload), of type ``typ``, to ``who``, departed at ``d``."""
    slot = alloc(S)
    evf = S[EV_FLOAT]
    evi = S[EV_INT]
    for j in range(evf.shape[1]):
        evf[slot, j] = evf[src, j]
    evi[slot, E_PAY] = 0
    evf[slot, EF_TDEP] = d
    address(S, slot, typ, who, evi[src, E_KIND], who, evi[src, E_INDEX])
    evi[slot, E_AUX] = evi[src, E_AUX]
    evi[slot, E_FRAME] = evi[src, E_FRAME]
    return slot


@jit
def _emit(S, src, first, m, d):  # type: ignore[no-untyped-def]
    """Queue the ``m`` elements in order from ring row ``first`` (``d``: the last
    departure) as one batch, or as a plain delivery event if there is one."""
    if m == 1:
        _singles(S, src, first, 1, d)
        return
    slot = _slot(S, src, EV_BATCH, S[BAT_W][first], d)
    evi = S[EV_INT]
    evi[slot, E_SEQ] = first
    evi[slot, E_NEXT] = m
    push_key(S, S[BAT_T][first], S[BAT_K][first] | slot)
    S[INTS][I_BPUSH] += 1


@jit
def _singles(S, src, first, m, d):  # type: ignore[no-untyped-def]
    """Queue the ``m`` elements from ring row ``first`` as plain delivery events, in
    sequence order (``d``: the broadcast's last departure, the slots' ``EF_TDEP``, which
    only QoS 1 over datagram and the CPU stage read: :func:`applies`)."""
    r = S[BAT_T].shape[0]
    i = first
    for _ in range(m):
        slot = _slot(S, src, EV_CLIENT, S[BAT_W][i], d)
        push_key(S, S[BAT_T][i], S[BAT_K][i] | slot)
        _consume(S, i)
        i = i + 1 if i + 1 < r else 0
    S[INTS][I_BSING] += m


@jit
def fan_out(S, src, kind, index, att, scaled, sc, d):  # type: ignore[no-untyped-def]
    """The broker's deliveries of the broadcast in slot ``src`` (after :func:`fits`), the
    first departing after ``d``: the operations of its per-message loop (``broker``: the
    delivery service, scaled by ``sc`` if ``scaled``; ``_deliver``'s hop: serialization,
    latency, loss; a sequence number per delivery not lost), queued as one batch if no
    arrival is earlier than the one before, else one event per delivery. Returns the
    last departure."""
    bc = S[BCAST]
    bt = S[BAT_T]
    bk = S[BAT_K]
    bw = S[BAT_W]
    iv = S[INTS]
    r = bt.shape[0]
    wb = S[WIRE_BYTES][kind]
    h = iv[I_BHEAD]
    first = h
    m = 0
    last = 0.0
    split = False
    for j in range(S[CPU_IP][CP_NSUB]):
        sub = bc[j]
        x = draw_at(S, SVC_DEL, kind, sub, index, att, False)
        if scaled:
            x = x * sc
        d += x
        done = count(S, sub, 0, wb, d)  # primitives.hop of the delivery, without its slot
        arr, lost = fly(S, sub, 0, kind, sub, index, 0, False, done, d)
        if lost:
            continue
        e = iv[I_EID]  # the sequence number the specification's push takes
        iv[I_EID] = e + 1
        iv[I_NEV] += 1
        split = split or (m > 0 and arr < last)  # out of order: one event per delivery
        bt[h] = arr
        bk[h] = e << SLOT_BITS
        bw[h] = sub
        iv[I_BUSED] += 1
        h = h + 1 if h + 1 < r else 0
        m += 1
        last = arr
    iv[I_BHEAD] = h
    if split:
        _singles(S, src, first, m, d)
    elif m > 0:
        _emit(S, src, first, m, d)
    return d


@jit
def head(S, s):  # type: ignore[no-untyped-def]
    """Batch ``s``'s head delivery is due: its subscriber becomes the slot's receiver and
    subject (the fields ``_deliver`` gives its slot); the element is delivered."""
    evi = S[EV_INT]
    i = evi[s, E_SEQ]
    w = S[BAT_W][i]
    evi[s, E_WHO] = w
    evi[s, E_SUBJ] = w
    _consume(S, i)
    S[INTS][I_BELEM] += 1


@jit
def requeue(S, s, c, p):  # type: ignore[no-untyped-def]
    """After its head delivery ran: batch ``s``, taken at arena row ``p`` of run ``c``,
    goes back under its next element's key; False if it has none (its slot is freed).

    In place (row ``p``, the run's head again) when that key precedes the run's next
    entry, or the run has none: the run stays sorted and the loop compares its head with
    the heap and the pending buffer as for any run. Else into the pending buffer.
    """
    evi = S[EV_INT]
    m = evi[s, E_NEXT] - 1
    if m == 0:
        return False
    i = evi[s, E_SEQ] + 1
    if i == S[BAT_T].shape[0]:
        i = 0
    evi[s, E_SEQ] = i
    evi[s, E_NEXT] = m
    t = S[BAT_T][i]
    k = S[BAT_K][i] | s
    if not back_in_place(S, c, p, t, k):
        push_key(S, t, k)
        S[INTS][I_BREIN] += 1
    return True
