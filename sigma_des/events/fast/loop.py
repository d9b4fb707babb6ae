"""The compiled message core's entry points: publishes and the event loop (numba).

The per-message engine (:mod:`sigma_des.events.engine` over
:mod:`sigma_des.net.network`) is the executable specification. The compiled core
runs the same message model — access-link FIFOs, the broker's FIFO, host cores,
node triggers, state publishes and command deliveries — as a loop over a k-way
merge of sorted runs of ``(time, sequence)`` keys held in numpy arrays
(:mod:`~sigma_des.events.fast.queue`: the heap orders only the runs' heads). It performs the same
floating point operations in the same order as the specification and numbers
events in the same relative order, so simultaneous events are broken the same way
and the results are bit-identical (docs/MODEL.md, "Engines").

All state is one state tuple (:data:`~sigma_des.events.fast.layout.FIELDS`), shared with the
Python driver (:mod:`sigma_des.events.fast.driver`). :func:`advance` hands control
back to Python, between two events, when something needs Python: a time-warp
rollback (its physics re-simulation is batched: Python owes it until the node's
next state publish, ``NEED_RESIM``), a job whose cost includes rollback draws, a
full delivery buffer, a full event table, a completed Lock-Step barrier, or a random
draw that is not in the draw tables (then the driver falls back to the
per-message engine). Random numbers are never drawn here: Python fills per-index
rows of the draw tables from the very same counter-based samplers the
specification uses, and the loop reads them.
"""

from __future__ import annotations

from sigma_des.events.fast.broker import broker
from sigma_des.events.fast.layout import (
    DRAW_MISS,
    E_AUX,
    E_FRAME,
    E_TYPE,
    E_WHO,
    EF_L,
    EF_PAY,
    EF_TPUB,
    EV_BROKER,
    EV_CLIENT,
    EV_FLOAT,
    EV_INT,
    I_ERR,
    I_FREE,
    I_LAT,
    I_OUT,
    I_PEND,
    INTS,
    IPARAMS,
    K_COMMAND,
    K_REREQ,
    K_TRIGGER,
    LAT_BUF,
    NEED_FLUSH,
    NEED_RESIM,
    NEED_SPACE,
    OK,
    OUT_INT,
    Q_ACK,
    Q_INT,
    Q_M,
    Q_N,
    Q_QOS1S,
    QI_HAS,
)
from sigma_des.events.fast.node import at_node, done, reserve, resim_due
from sigma_des.events.fast.primitives import alloc, count, jit, release, send_up
from sigma_des.events.fast.queue import peek, take
from sigma_des.events.fast.server import at_server, delivered

__all__ = ["advance", "publish_commands", "publish_rerequest", "publish_trigger", "reserve"]


@jit
def _client(S, s, now):  # type: ignore[no-untyped-def]
    """A delivery reaches its subscriber (Network._client_receive + deliver)."""
    q = S[IPARAMS]
    sub = S[EV_INT][s, E_WHO]
    if q[Q_QOS1S]:
        count(S, sub, 1, q[Q_ACK], now)
    delivered(S, s, now)
    if sub == q[Q_N]:
        at_server(S, s, now)
    else:
        at_node(S, s, now)


@jit
def publish_trigger(S, k, t, hlc_l, hlc_c):  # type: ignore[no-untyped-def]
    """The server publishes trigger ``k`` at ``t`` (with its HLC stamp)."""
    ns = alloc(S)
    S[EV_FLOAT][ns, EF_TPUB] = t
    S[EV_FLOAT][ns, EF_L] = hlc_l
    S[EV_INT][ns, E_AUX] = hlc_c
    n = S[IPARAMS][Q_N]
    send_up(S, ns, n, K_TRIGGER, n, k, t)


@jit
def publish_commands(S, tick, stamp, nodes, rows, t):  # type: ignore[no-untyped-def]
    """The server publishes ``rows[i]`` to each node ``i`` of ``nodes``, in order."""
    n = S[IPARAMS][Q_N]
    m = S[IPARAMS][Q_M]
    for i in nodes:
        ns = alloc(S)
        S[EV_FLOAT][ns, EF_TPUB] = t
        for j in range(m):
            S[EV_FLOAT][ns, EF_PAY + j] = rows[i, j]
        S[EV_INT][ns, E_AUX] = stamp
        send_up(S, ns, n, K_COMMAND, i, tick, t)


@jit
def publish_rerequest(S, node, frame, index, t):  # type: ignore[no-untyped-def]
    """Lock-Step: the server asks ``node`` again for its state of ``frame``."""
    ns = alloc(S)
    S[EV_FLOAT][ns, EF_TPUB] = t
    S[EV_INT][ns, E_FRAME] = frame
    send_up(S, ns, S[IPARAMS][Q_N], K_REREQ, node, index, t)


@jit
def _full(S):  # type: ignore[no-untyped-def]
    """Whether a delivery buffer is full (Python must flush it)."""
    iv = S[INTS]
    lat_cap = S[LAT_BUF].shape[1]
    return (
        iv[I_OUT] >= S[OUT_INT].shape[0]
        or iv[I_LAT] >= lat_cap
        or iv[I_LAT + 1] >= lat_cap
        or iv[I_LAT + 2] >= lat_cap
    )


@jit
def advance(S, t_stop, strict):  # type: ignore[no-untyped-def]
    """Process message events up to ``t_stop`` (``< t_stop`` if ``strict``).

    Returns:
        OK when done, else the reason Python must act before the next event.
    """
    iv = S[INTS]
    qi = S[Q_INT]
    n = S[IPARAMS][Q_N]
    while True:
        t = peek(S)
        if not qi[QI_HAS]:
            break
        if t > t_stop or (strict and t >= t_stop):
            return OK
        if iv[I_FREE] < n + 4:
            return NEED_SPACE
        if _full(S):
            return NEED_FLUSH
        if resim_due(S):
            return NEED_RESIM
        s = take(S)
        typ = S[EV_INT][s, E_TYPE]
        if typ == EV_CLIENT:
            _client(S, s, t)
        elif typ == EV_BROKER:
            broker(S, s, t)
        else:
            done(S, s, t)
        release(S, s)
        if iv[I_ERR]:
            return DRAW_MISS
        if iv[I_PEND]:
            code = iv[I_PEND]
            iv[I_PEND] = 0
            return code
    return OK
