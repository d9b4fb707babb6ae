"""MQTT QoS 1 over datagram in the compiled message core (docs/concepts/model.md, "Network").

The transport side of a PUBLISH's hop, the same operations in the same order as
:mod:`sigma_des.net.network`: :func:`send` is ``Network._send_publish`` with
``_schedule_resend`` (a first transmission, a resend or a redelivery: the arrival
is queued first, then, if it is lost or later than ``qos1_timeout``, the resend
timer); :func:`puback_broker` and :func:`puback_client` are ``Network._puback``
from the broker to the publisher and from a subscriber to the broker, with the
resend a lost or late PUBACK causes while the sender's timer still runs. A resend
timer is an event slot holding a copy of the message, its attempt and the type of
the event it will resend (:mod:`sigma_des.events.fast.resend` handles it).
Without QoS 1 over datagram :func:`send` is one hop
(:func:`~sigma_des.events.fast.primitives.hop`), or a stream segment with hold-back
(:mod:`sigma_des.events.fast.stream`) on a link with loss or random latency.
"""

from __future__ import annotations

from sigma_des.events.fast.channel import hop
from sigma_des.events.fast.codes import (
    E_ATT,
    E_RTYPE,
    E_TACT,
    E_TYPE,
    E_WHO,
    EF_TDEP,
    EF_TPUB,
    EV_BROKER,
    EV_NSEND,
    EV_RESEND,
    EV_SEND,
    Q_ACK,
    Q_N,
    T_GAVE,
    T_QOS1D,
    T_RETRIES,
    T_RETX,
    T_STREAM,
    TA_RESEND,
    TF_TIMEOUT,
)
from sigma_des.events.fast.cpu import net_span, span, threaded
from sigma_des.events.fast.layout import (
    CPU_DEM,
    CPU_PROC,
    EV_FLOAT,
    EV_INT,
    IPARAMS,
    TR_FPARAMS,
    TR_INTS,
    TR_PARAMS,
)
from sigma_des.events.fast.primitives import (
    address,
    alloc,
    copy_payload,
    count,
    fly,
    jit,
    key_of,
    push,
    release,
)
from sigma_des.events.fast.stream import stream_send

__all__ = ["copy_slot", "net_send", "net_sent", "puback_broker", "puback_client", "send",
           "send_burst_done", "send_up"]


@jit
def copy_slot(S, src, dst):  # type: ignore[no-untyped-def]
    """Copy every column of event slot ``src`` into the free slot ``dst``, its payload
    into a row of ``dst``'s own (each slot frees its row)."""
    evi = S[EV_INT]
    evf = S[EV_FLOAT]
    for j in range(evi.shape[1]):
        evi[dst, j] = evi[src, j]
    for j in range(evf.shape[1]):
        evf[dst, j] = evf[src, j]
    copy_payload(S, src, dst)


@jit
def _schedule(S, tm, when):  # type: ignore[no-untyped-def]
    """Network._schedule_resend: the copy in slot ``tm`` is resent at ``when``, or given up."""
    evi = S[EV_INT]
    ti = S[TR_INTS]
    attempt = evi[tm, E_ATT]
    if attempt >= S[TR_PARAMS][T_RETRIES]:
        ti[T_GAVE] += 1
        release(S, tm)
        return
    ti[T_RETX] += 1
    evi[tm, E_RTYPE] = evi[tm, E_TYPE]
    evi[tm, E_TYPE] = EV_RESEND
    evi[tm, E_TACT] = TA_RESEND
    evi[tm, E_ATT] = attempt + 1
    push(S, when, tm)


@jit
def send(S, slot, t):  # type: ignore[no-untyped-def]
    """The addressed PUBLISH in ``slot`` leaves its sender at ``t`` (its attempt set)."""
    tp = S[TR_PARAMS]
    if not tp[T_QOS1D]:
        cls = 1 if S[EV_INT][slot, E_WHO] == S[IPARAMS][Q_N] else 0
        if tp[T_STREAM + cls]:
            stream_send(S, slot, t)
        else:
            hop(S, slot, t)
        return
    S[EV_FLOAT][slot, EF_TDEP] = t  # when this try left (the PUBACK's timer starts)
    tm = alloc(S)  # the resend's copy, made before the hop frees a lost message
    copy_slot(S, slot, tm)
    arr, lost = hop(S, slot, t)
    when = t + S[TR_FPARAMS][TF_TIMEOUT]
    if lost or arr > when:
        _schedule(S, tm, when)
    else:
        release(S, tm)


@jit
def send_up(S, slot, client, kind, subject, index, t):  # type: ignore[no-untyped-def]
    """``client`` publishes the PUBLISH in ``slot`` (payload already there) at ``t``
    (Network._send): after its process's burst, if its demand is not zero, it leaves
    for the broker (an ``EV_SEND`` event at the burst's end: :func:`send_burst_done`)."""
    address(S, slot, EV_BROKER, client, kind, subject, index)
    p = S[CPU_PROC][client]
    if p < 0:
        send(S, slot, t)
        return
    S[EV_INT][slot, E_TYPE] = EV_SEND
    start, end = span(S, p, S[CPU_DEM][client], t)
    S[EV_FLOAT][slot, EF_TPUB] = start  # Network._client_publish: stamped at the start
    push(S, end, slot)


@jit
def send_burst_done(S, s, now):  # type: ignore[no-untyped-def]
    """The publish burst of the PUBLISH in slot ``s`` ends: its first try leaves
    (Network._publish_try; the event's slot is freed after it, so a copy travels).
    With ``lock_switch`` the copy goes through its process's outbox instead
    (:mod:`sigma_des.events.fast.outbox`, called by the loop)."""
    net_send(S, burst_copy(S, s), now)


@jit
def net_send(S, ns, now):  # type: ignore[no-untyped-def]
    """Network._net_send: the PUBLISH in ``ns`` (a slot of its own) leaves now, or from
    a process with a network thread when that thread takes it (an ``EV_NSEND`` event at
    that burst's start: :func:`net_sent`)."""
    p = S[CPU_PROC][S[EV_INT][ns, E_WHO]]
    if p >= 0 and threaded(S, p):
        S[EV_INT][ns, E_TYPE] = EV_NSEND
        push(S, net_span(S, p, now, False)[0], ns)
        return
    S[EV_INT][ns, E_TYPE] = EV_BROKER
    send(S, ns, now)


@jit
def net_sent(S, s, now):  # type: ignore[no-untyped-def]
    """The network thread takes the PUBLISH in ``s``: its first try leaves (a copy: the
    event's slot is freed after it)."""
    ns = burst_copy(S, s)
    S[EV_INT][ns, E_TYPE] = EV_BROKER
    send(S, ns, now)


@jit
def burst_copy(S, s):  # type: ignore[no-untyped-def]
    """A copy of the PUBLISH in slot ``s`` (the event's slot is freed after it)."""
    ns = alloc(S)
    copy_slot(S, s, ns)
    return ns


@jit
def _puback(S, s, up, t, now):  # type: ignore[no-untyped-def]
    """Network._puback for the PUBLISH in slot ``s`` (its try left at ``EF_TDEP``),
    sent at ``t`` on its client's link; resend it if the sender's timer fires first."""
    kind, subj, index = key_of(S, s)
    client = S[EV_INT][s, E_WHO]
    attempt = S[EV_INT][s, E_ATT]
    done = count(S, client, up, S[IPARAMS][Q_ACK], t)
    arr, lost = fly(S, client, up, kind, subj, index, attempt, True, done, t)
    when = S[EV_FLOAT][s, EF_TDEP] + S[TR_FPARAMS][TF_TIMEOUT]
    if now <= when and (lost or arr > when):
        tm = alloc(S)
        copy_slot(S, s, tm)
        _schedule(S, tm, when)


@jit
def puback_broker(S, s, t_ack, now):  # type: ignore[no-untyped-def]
    """The broker acknowledges the PUBLISH in slot ``s`` (received ``now``) at ``t_ack``."""
    _puback(S, s, 0, t_ack, now)


@jit
def puback_client(S, s, now):  # type: ignore[no-untyped-def]
    """The subscriber of the delivery in slot ``s`` acknowledges it on arrival ``now``."""
    _puback(S, s, 1, now, now)
