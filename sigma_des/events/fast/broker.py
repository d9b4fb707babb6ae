"""The broker in the compiled message core (docs/concepts/model.md, "Network").

One FIFO server (the Lindley recursion, one departure after another): a PUBLISH
takes its publish service, then each matching subscriber its delivery service,
and every delivery leaves over the subscriber's down link — the same operations,
in the same order, as :mod:`sigma_des.net.network` and :mod:`sigma_des.net.broker`.
A broadcast fans out in batches where it can
(:mod:`~sigma_des.events.fast.fanout`: the same operations, fewer queue entries).
With a CPU stage the broker is a process (:mod:`~sigma_des.events.fast.cpu`): a
service starts on its machine's core, its times are scaled by the background
slow-down, and the core is held until the last delivery leaves.
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    CP_BROKER,
    CP_NSUB,
    E_ATT,
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_WHO,
    EF_TDEP,
    EV_CLIENT,
    F_BUSY,
    F_MAXWAIT,
    F_WORK,
    G_END,
    G_WARMUP,
    I_BNOFIT,
    K_REPUB,
    K_STATE,
    Q_ACK,
    Q_FAN,
    Q_N,
    Q_QOS1S,
    SVC_DEL,
    SVC_PUB,
    T_QOS1D,
)
from sigma_des.events.fast.cpu import acquire, hold, run_wait
from sigma_des.events.fast.fanout import fan_out, fits
from sigma_des.events.fast.layout import (
    BCAST,
    CL_OF,
    CPU_IP,
    CPU_SCALE,
    EV_FLOAT,
    EV_INT,
    FLOATS,
    FPARAMS,
    INTS,
    IPARAMS,
    TR_PARAMS,
)
from sigma_des.events.fast.primitives import (
    address,
    alloc,
    copy_payload,
    count,
    draw_at,
    in_window,
    jit,
    key_of,
)
from sigma_des.events.fast.transport import puback_broker, send

__all__ = ["broker", "serve_delivery"]


@jit
def _deliver(S, src, sub, subject, d):  # type: ignore[no-untyped-def]
    """A copy of the PUBLISH in ``src`` leaves the broker at ``d`` for ``sub``."""
    slot = alloc(S)
    evf = S[EV_FLOAT]
    evi = S[EV_INT]
    for j in range(evf.shape[1]):
        evf[slot, j] = evf[src, j]
    copy_payload(S, src, slot)
    evf[slot, EF_TDEP] = d
    address(S, slot, EV_CLIENT, sub, evi[src, E_KIND], subject, evi[src, E_INDEX])
    evi[slot, E_AUX] = evi[src, E_AUX]
    evi[slot, E_FRAME] = evi[src, E_FRAME]
    send(S, slot, d)


@jit
def _work(S, a, b):  # type: ignore[no-untyped-def]
    g = S[FPARAMS]
    lo = a if a > g[G_WARMUP] else g[G_WARMUP]
    hi = b if b < g[G_END] else g[G_END]
    if hi > lo:
        S[FLOATS][F_WORK] += hi - lo


@jit
def _length(S, kind, subject, index, att, s_pub, sc):  # type: ignore[no-untyped-def]
    """A PUBLISH's whole service on the broker's core (Broker.serve_publish's ``length``:
    the scaled publish service, then each scaled delivery added in delivery order)."""
    n = S[IPARAMS][Q_N]
    length = s_pub
    if subject == n:
        bc = S[BCAST]
        for j in range(S[CPU_IP][CP_NSUB]):
            length += draw_at(S, SVC_DEL, kind, bc[j], index, att, False) * sc
    else:
        length += draw_at(S, SVC_DEL, kind, subject, index, att, False) * sc
    return length


@jit
def broker(S, s, now):  # type: ignore[no-untyped-def]
    """The PUBLISH in slot ``s`` reaches the broker at ``now`` (Broker.serve_publish and
    Network._broker_receive; with a CPU stage the broker's process takes a core)."""
    kind, subject, index = key_of(S, s)
    ff = S[FLOATS]
    q = S[IPARAMS]
    n = q[Q_N]
    att = S[EV_INT][s, E_ATT]  # the PUBLISH's attempt keys the service draws
    s_pub = draw_at(S, SVC_PUB, kind, subject, index, att, False)
    bp = S[CPU_IP][CP_BROKER]
    scaled = bp >= 0
    c = 0
    sc = 1.0
    if scaled:
        sc = S[CPU_SCALE][bp]
        s_pub = s_pub * sc
        length = _length(S, kind, subject, index, att, s_pub, sc)
        start, c = acquire(S, bp, now, length, run_wait(S, bp, now, length / sc, length))
    else:
        busy = ff[F_BUSY]
        start = now if now > busy else busy
    if in_window(S, now):
        ff[F_MAXWAIT] = max(ff[F_MAXWAIT], start - now)
    if q[Q_QOS1S]:
        count(S, S[EV_INT][s, E_WHO], 0, q[Q_ACK], start + s_pub)
    elif S[TR_PARAMS][T_QOS1D]:
        puback_broker(S, s, start + s_pub, now)
    d = start + s_pub
    nsub = S[CPU_IP][CP_NSUB]
    if subject == n and q[Q_FAN] and fits(S, s, nsub):  # in batches (fanout.py)
        d = fan_out(S, s, kind, index, att, scaled, sc, d)
    elif subject == n:  # a broadcast: one delivery per subscriber, keyed by the subscriber
        if q[Q_FAN]:
            S[INTS][I_BNOFIT] += nsub  # for tally.breakdown
        bc = S[BCAST]
        for j in range(nsub):
            sub = bc[j]
            x = draw_at(S, SVC_DEL, kind, sub, index, att, False)
            if scaled:
                x = x * sc
            d += x
            _deliver(S, s, sub, sub, d)
    else:  # to the server, or to the client of the node it is about
        sub = n if kind == K_STATE or kind == K_REPUB else S[CL_OF][subject]
        x = draw_at(S, SVC_DEL, kind, subject, index, att, False)
        if scaled:
            x = x * sc
        d += x
        _deliver(S, s, sub, subject, d)
    ff[F_BUSY] = d
    if scaled:
        hold(S, bp, now, start, c, d)
    _work(S, start, d)


@jit
def serve_delivery(S, kind, subject, index, attempt, now):  # type: ignore[no-untyped-def]
    """Broker.serve_delivery: one QoS 1 redelivery asked for ``now``; its departure."""
    ff = S[FLOATS]
    s_del = draw_at(S, SVC_DEL, kind, subject, index, attempt, False)
    bp = S[CPU_IP][CP_BROKER]
    if bp < 0:
        busy = ff[F_BUSY]
        start = now if now > busy else busy
        end = start + s_del
    else:
        length = s_del * S[CPU_SCALE][bp]
        start, c = acquire(S, bp, now, length, run_wait(S, bp, now, s_del, length))
        end = start + length
        hold(S, bp, now, start, c, end)
    ff[F_BUSY] = end
    _work(S, start, end)
    return end
