"""Transport events of the compiled message core, and their draws on demand.

:func:`resend` handles a transport event: a QoS 1 resend timer (over datagram) — a
PUBLISH resent by its publisher (``Network._publish_try`` with the next attempt)
or a delivery resent by the broker (``Network._redeliver``: one more delivery
service, then the hop) — or a stream segment's retry or arrival
(:mod:`sigma_des.events.fast.stream`). Draws of attempts >= 1 are not in the main
draw tables; before an event whose message is such an attempt, :func:`missing`
finds whether its rows are in the attempt tables and, if not, names them for Python
(:class:`~sigma_des.events.fast.attempts.AttemptTables`), which fills them before
the loop takes that event: draws stay a pure function of their key.
"""

from __future__ import annotations

from sigma_des.events.fast.broker import serve_delivery
from sigma_des.events.fast.codes import (
    E_ATT,
    E_INDEX,
    E_KIND,
    E_RTYPE,
    E_TACT,
    E_TYPE,
    EF_TDEP,
    EV_BROKER,
    EV_RESEND,
    T_FATT,
    T_FINDEX,
    T_FKIND,
    TA_ARRIVE,
    TA_RESEND,
    TA_RETRY,
)
from sigma_des.events.fast.layout import EV_FLOAT, EV_INT, TR_INTS, X_FIRST, X_TAG
from sigma_des.events.fast.primitives import alloc, attempt_key, jit, key_of
from sigma_des.events.fast.stream import stream_arrive, stream_try
from sigma_des.events.fast.transport import copy_slot, send

__all__ = ["missing", "resend"]


@jit
def missing(S, slot):  # type: ignore[no-untyped-def]
    """Whether the next event's message (in ``slot``) needs attempt draws not yet in
    the tables. If so, the request ``(kind, index, attempt)`` is written for Python.
    """
    evi = S[EV_INT]
    attempt = evi[slot, E_ATT]
    if attempt == 0 or (evi[slot, E_TYPE] == EV_RESEND and evi[slot, E_TACT] >= TA_ARRIVE):
        return False  # a first try, or a stream arrival (it draws nothing)
    kind = evi[slot, E_KIND]
    c = S[X_FIRST][kind]
    if c < 0:
        return False
    index = evi[slot, E_INDEX]
    key, r = attempt_key(S, index, attempt)
    if S[X_TAG][c, r] == key:
        return False
    ti = S[TR_INTS]
    ti[T_FKIND] = kind
    ti[T_FINDEX] = index
    ti[T_FATT] = attempt
    return True


@jit
def resend(S, s, now):  # type: ignore[no-untyped-def]
    """The transport event in slot ``s`` at ``now``: a QoS 1 resend timer fires (send its
    copy again), a stream segment is tried again or arrives (its copy goes on)."""
    ns = alloc(S)
    copy_slot(S, s, ns)
    evi = S[EV_INT]
    act = evi[s, E_TACT]
    if act == TA_RETRY:  # Links._stream_retry
        stream_try(S, ns, now)
        return
    if act != TA_RESEND:  # Links._stream_arrive (a segment or a give-up)
        stream_arrive(S, ns, now)
        return
    evi[ns, E_TYPE] = evi[s, E_RTYPE]
    if evi[ns, E_TYPE] == EV_BROKER:  # Network._publish_try, next attempt
        send(S, ns, now)
        return
    kind, subj, index = key_of(S, ns)  # Network._redeliver
    depart = serve_delivery(S, kind, subj, index, evi[ns, E_ATT], now)
    S[EV_FLOAT][ns, EF_TDEP] = depart
    send(S, ns, depart)
