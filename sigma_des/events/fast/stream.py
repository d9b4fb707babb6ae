"""The stream transport with hold-back in the compiled message core (docs/concepts/model.md,
"Network").

On a link with loss or random latency a ``stream`` delivers each connection's
segments in order (:mod:`sigma_des.net.links`: ``transmit``, ``_stream_try``,
``_stream_retry``, ``_stream_arrive``), and so does this module, with the same
operations in the same order: a segment gets its connection's next sequence
number; a lost try is resent after ``rto · 2^attempt`` or given up after
``max_retries`` (a give-up still takes its place in the sequence, at the time of
the last try); an arrival joins the connection's pending list, sorted by sequence
number, and when it fills the gap at the head every consecutive segment is handed
on in order, inside the arrival's event (:func:`next_ready`, called by the loop).
The segment's own event slot travels: it is a transport event (``EV_RESEND``,
action ``TA_RETRY``/``TA_ARRIVE``/``TA_GONE``) until it is delivered, then its
original type again.
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    C_DELIVER,
    C_HEAD,
    C_LOST,
    C_SEQ,
    C_TAIL,
    CP_APP,
    E_ATT,
    E_NEXT,
    E_PREV,
    E_RTYPE,
    E_SEQ,
    E_TACT,
    E_TYPE,
    E_WHO,
    EF_TRECV,
    EV_BROKER,
    EV_RESEND,
    T_DRAIN,
    T_GAVE,
    T_RETRIES,
    T_RETX,
    TA_ARRIVE,
    TA_GONE,
    TA_READ,
    TA_RETRY,
    TF_RTO,
)
from sigma_des.events.fast.cpu import net_span, threaded
from sigma_des.events.fast.layout import (
    CONN,
    CPU_IP,
    CPU_PROC,
    EV_FLOAT,
    EV_INT,
    TR_FLOATS,
    TR_FPARAMS,
    TR_INTS,
    TR_PARAMS,
    WIRE_BYTES,
)
from sigma_des.events.fast.primitives import count, fly, jit, key_of, push, put_int, release
from sigma_des.net.resend import stream_backoff

__all__ = ["next_ready", "read_held", "stream_arrive", "stream_send", "stream_try"]

#: The stream's resend wait ``rto · 2^attempt``, compiled from the net's one definition.
_backoff = jit(stream_backoff)


@jit
def _up(S, slot):  # type: ignore[no-untyped-def]
    """The direction of the segment's connection: up for a PUBLISH to the broker."""
    return 1 if S[EV_INT][slot, E_RTYPE] == EV_BROKER else 0


@jit
def stream_try(S, slot, t):  # type: ignore[no-untyped-def]
    """Links._stream_try: try ``E_ATT`` of the segment in ``slot`` leaves at ``t``."""
    evi = S[EV_INT]
    up = _up(S, slot)
    client = evi[slot, E_WHO]
    kind, subj, index = key_of(S, slot)
    att = evi[slot, E_ATT]
    done = count(S, client, up, S[WIRE_BYTES][kind], t)
    arr, lost = fly(S, client, up, kind, subj, index, att, False, done, t)
    evi[slot, E_TYPE] = EV_RESEND
    if not lost:
        evi[slot, E_TACT] = TA_ARRIVE
        push(S, arr, slot)
        return
    if att == 0:
        S[CONN][C_LOST, up, client] += 1
    ti = S[TR_INTS]
    if att >= S[TR_PARAMS][T_RETRIES]:
        ti[T_GAVE] += 1
        evi[slot, E_TACT] = TA_GONE
        push(S, t, slot)
        return
    ti[T_RETX] += 1
    evi[slot, E_TACT] = TA_RETRY
    evi[slot, E_ATT] = att + 1
    push(S, t + _backoff(S[TR_FPARAMS][TF_RTO], att), slot)


@jit
def stream_send(S, slot, t):  # type: ignore[no-untyped-def]
    """Links.transmit on a stream with hold-back: the addressed PUBLISH in ``slot``."""
    evi = S[EV_INT]
    evi[slot, E_RTYPE] = evi[slot, E_TYPE]
    up = _up(S, slot)
    client = evi[slot, E_WHO]
    cn = S[CONN]
    put_int(S, slot, E_SEQ, cn[C_SEQ, up, client])
    cn[C_SEQ, up, client] += 1
    stream_try(S, slot, t)


@jit
def stream_arrive(S, ns, now):  # type: ignore[no-untyped-def]
    """Links._stream_arrive: segment ``ns`` (a copy of the event's) joins its connection's
    pending list by sequence number; if it is the next to deliver, the drain starts."""
    evi = S[EV_INT]
    up = _up(S, ns)
    client = evi[ns, E_WHO]
    cn = S[CONN]
    seq = evi[ns, E_SEQ]
    p = cn[C_TAIL, up, client]  # arrivals come nearly in order: search from the tail
    while p >= 0 and evi[p, E_SEQ] > seq:
        p = evi[p, E_PREV]
    if p < 0:
        nxt = cn[C_HEAD, up, client]
        cn[C_HEAD, up, client] = ns
    else:
        nxt = evi[p, E_NEXT]
        evi[p, E_NEXT] = ns
    evi[ns, E_PREV] = p
    evi[ns, E_NEXT] = nxt
    if nxt < 0:
        cn[C_TAIL, up, client] = ns
    else:
        evi[nxt, E_PREV] = ns
    att = evi[ns, E_ATT]
    arrived = evi[ns, E_TACT] == TA_ARRIVE
    if att > 0 or not arrived:
        cn[C_LOST, up, client] -= 1
    if up == 0 and arrived and (att > 0 or (cn[C_LOST, up, client] > 0
                                            and seq != cn[C_DELIVER, up, client])):
        read_held(S, ns, now, att > 0)
    if seq == cn[C_DELIVER, up, client]:
        S[TR_INTS][T_DRAIN] = 1 + up * cn.shape[2] + client
        S[TR_FLOATS][0] = now


@jit
def read_held(S, ns, now, resent):  # type: ignore[no-untyped-def]
    """Network.read_held: the downlink segment ``ns``, held behind a lost one or arriving
    on a resend; a receiving process with a network thread reads it now (marked ``TA_READ``,
    with when the loop may take it in ``EF_TRECV``: that burst's end for a held copy,
    now for a resent one; :func:`~sigma_des.events.fast.clients.receive`)."""
    if not S[CPU_IP][CP_APP]:
        return
    p = S[CPU_PROC][S[EV_INT][ns, E_WHO]]
    if p >= 0 and threaded(S, p):
        end = net_span(S, p, now, True)[1]
        S[EV_FLOAT][ns, EF_TRECV] = now if resent else end
        S[EV_INT][ns, E_TACT] = TA_READ


@jit
def next_ready(S):  # type: ignore[no-untyped-def]
    """The draining connection's next in-order segment, as its original event (-1: none).

    Given-up segments are passed over (freed); the drain ends at the first gap.
    """
    ti = S[TR_INTS]
    cn = S[CONN]
    evi = S[EV_INT]
    d = ti[T_DRAIN] - 1
    up = d // cn.shape[2]
    client = d % cn.shape[2]
    while True:
        h = cn[C_HEAD, up, client]
        if h < 0 or evi[h, E_SEQ] != cn[C_DELIVER, up, client]:
            ti[T_DRAIN] = 0
            return -1
        nxt = evi[h, E_NEXT]
        cn[C_HEAD, up, client] = nxt
        if nxt < 0:
            cn[C_TAIL, up, client] = -1
        else:
            evi[nxt, E_PREV] = -1
        cn[C_DELIVER, up, client] += 1
        if evi[h, E_TACT] == TA_GONE:
            release(S, h)
            continue
        evi[h, E_TYPE] = evi[h, E_RTYPE]
        evi[h, E_ATT] = 0  # the MQTT attempt of a stream PUBLISH is always 0
        return h
