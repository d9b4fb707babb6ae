"""The compiled message core's entry points: publishes and the event loop (numba).

The per-message engine (:mod:`sigma_des.events.engine` over
:mod:`sigma_des.net.network`) is the executable specification. The compiled core
runs the same message model — access-link FIFOs, the broker's FIFO, host cores,
node triggers, state publishes and command deliveries — as a loop over a k-way
merge of sorted runs of ``(time, sequence)`` keys held in numpy arrays
(:mod:`~sigma_des.events.fast.queue`: the heap orders only the runs' heads). It performs the same
floating point operations in the same order as the specification and numbers
events in the same relative order, so simultaneous events are broken the same way
and the results are bit-identical (docs/concepts/engines.md).

All state is one state tuple (:data:`~sigma_des.events.fast.layout.FIELDS`), shared with the
Python driver (:mod:`sigma_des.events.fast.driver`). :func:`advance` hands control
back to Python, between two events, when something needs Python: a deferred
time-warp re-simulation (the rollbacks themselves run here, :mod:`~sigma_des.events.fast.warp`;
their physics is batched: Python owes it until the node's next state publish,
``NEED_RESIM``), a second rollback of such a node, a job whose rollback draws are not
in their table yet, a full delivery buffer, a full event table, a completed Lock-Step
barrier, or a random draw that is not in the draw tables (then the driver falls back to
the per-message engine). Random numbers are never drawn here: Python fills per-index
rows of the draw tables from the very same counter-based samplers the
specification uses, and the loop reads them.
"""

from __future__ import annotations

from sigma_des.events.fast.broker import broker
from sigma_des.events.fast.channel import requeue as chan_requeue
from sigma_des.events.fast.channel import take as chan_take
from sigma_des.events.fast.clients import hand_over, loop_receive, receive
from sigma_des.events.fast.codes import (
    CP_APP,
    CP_MAXMEM,
    CP_SWITCH,
    DRAW_MISS,
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_PAY,
    E_SUBJ,
    E_TYPE,
    E_WHO,
    EF_L,
    EF_TPUB,
    EF_TRECV,
    EV_BATCH,
    EV_BROKER,
    EV_CHAN,
    EV_CLIENT,
    EV_DONE,
    EV_LEAVE,
    EV_LOOP,
    EV_NSEND,
    EV_RESEND,
    EV_SEND,
    I_ERR,
    I_FREE,
    I_LAT,
    I_OUT,
    I_PEND,
    I_PFREE,
    K_COMMAND,
    K_REREQ,
    K_TRIGGER,
    NEED_FILL,
    NEED_FLUSH,
    NEED_RESIM,
    NEED_SPACE,
    OB_CAP,
    OK,
    Q_ACK,
    Q_M,
    Q_N,
    Q_QOS1S,
    Q_RING,
    QF_PMIN,
    QI_CUR,
    QI_HAS,
    QI_HEAP,
    QI_PMINK,
    QI_PN,
    SLOT_MASK,
    T_DRAIN,
    T_QOS1D,
    T_STREAM,
)
from sigma_des.events.fast.cpu import tick
from sigma_des.events.fast.fanout import head, requeue
from sigma_des.events.fast.job import owe, start_job
from sigma_des.events.fast.layout import (
    CPU_IP,
    EV_FLOAT,
    EV_INT,
    HEAP_K,
    HEAP_R,
    HEAP_T,
    INTS,
    IPARAMS,
    LAT_BUF,
    OBS_HIST,
    OUT_INT,
    POOL,
    Q_FLOAT,
    Q_INT,
    RESIM_PEND,
    RING_FRAME,
    RING_GEN,
    RING_OBS,
    RUN_END,
    RUN_K,
    RUN_POS,
    RUN_T,
    TALLY,
    TR_FLOATS,
    TR_INTS,
    TR_PARAMS,
)
from sigma_des.events.fast.node import at_node, done
from sigma_des.events.fast.outbox import burst_done, leave
from sigma_des.events.fast.prefetch import prefetch
from sigma_des.events.fast.primitives import (
    alloc,
    count,
    give_payload,
    jit,
    precedes,
    release,
    row_of,
)
from sigma_des.events.fast.queue import first, replace_top, view
from sigma_des.events.fast.resend import missing, resend
from sigma_des.events.fast.server import at_server, delivered
from sigma_des.events.fast.stateref import ref
from sigma_des.events.fast.stream import next_ready
from sigma_des.events.fast.transport import (
    burst_copy,
    net_sent,
    puback_client,
    send_burst_done,
    send_up,
)
from sigma_des.events.fast.warp import rollback

__all__ = ["advance", "owe_steps", "publish_commands", "publish_rerequest", "publish_trigger",
           "roll_back", "start", "tick"]


@jit
def _client(S, s, now):  # type: ignore[no-untyped-def]
    """A delivery reaches its subscriber (Network._client_receive + deliver)."""
    q = S[IPARAMS]
    sub = S[EV_INT][s, E_WHO]
    if q[Q_QOS1S]:
        count(S, sub, 1, q[Q_ACK], now)
    elif S[TR_PARAMS][T_QOS1D]:
        puback_client(S, s, now)
    if S[CPU_IP][CP_APP]:  # a receive burst or a host client's hand-over (clients.py)
        receive(S, s, now)
        return
    delivered(S, s, now)
    if sub == q[Q_N]:
        at_server(S, s, now)
    else:
        at_node(S, s, now)


@jit
def publish_trigger(S, k, t, hlc_l, hlc_c):  # type: ignore[no-untyped-def]
    """The server publishes trigger ``k`` at ``t`` (with its HLC stamp)."""
    S = ref(S)  # one pointer to the state for every call below
    ns = alloc(S)
    S[EV_FLOAT][ns, EF_TPUB] = t
    S[EV_FLOAT][ns, EF_L] = hlc_l
    S[EV_INT][ns, E_AUX] = hlc_c
    n = S[IPARAMS][Q_N]
    send_up(S, ns, n, K_TRIGGER, n, k, t)


@jit
def publish_commands(S, tick, stamp, nodes, rows, t):  # type: ignore[no-untyped-def]
    """The server publishes ``rows[i]`` to each node ``i`` of ``nodes``, in order."""
    S = ref(S)  # one pointer to the state for every call below
    n = S[IPARAMS][Q_N]
    m = S[IPARAMS][Q_M]
    pool = S[POOL]
    for i in nodes:
        ns = alloc(S)
        S[EV_FLOAT][ns, EF_TPUB] = t
        r = give_payload(S, ns)
        for j in range(m):
            pool[r, j] = rows[i, j]
        S[EV_INT][ns, E_AUX] = stamp
        send_up(S, ns, n, K_COMMAND, i, tick, t)


@jit
def publish_rerequest(S, node, frame, index, t):  # type: ignore[no-untyped-def]
    """Lock-Step: the server asks ``node`` again for its state of ``frame``."""
    S = ref(S)  # one pointer to the state for every call below
    ns = alloc(S)
    S[EV_FLOAT][ns, EF_TPUB] = t
    S[EV_INT][ns, E_FRAME] = frame
    send_up(S, ns, S[IPARAMS][Q_N], K_REREQ, node, index, t)


@jit
def roll_back(S, i, stamp, current, now):  # type: ignore[no-untyped-def]
    """Node ``i``'s rollback to ``stamp`` from ``current`` at ``now``, after Python flushed
    the node's earlier one (:func:`~sigma_des.events.fast.warp.rollback`)."""
    rollback(ref(S), i, stamp, current, now)


@jit
def owe_steps(S, i, steps, now):  # type: ignore[no-untyped-def]
    """Node ``i`` owes ``steps`` steps of a rollback Python re-simulated at once."""
    owe(ref(S), i, steps, now)


@jit
def start(S, i, now):  # type: ignore[no-untyped-def]
    """Node ``i``'s job start, once Python filled the rollback draws it owes."""
    start_job(ref(S), i, now)


@jit
def _full(S):  # type: ignore[no-untyped-def]
    """Whether a delivery buffer is full (Python must flush it): the next event may add
    one latency per node its client hands the message to (CP_MAXMEM; 1 per node client)."""
    iv = S[INTS]
    lat_cap = S[LAT_BUF].shape[1] + 1 - S[CPU_IP][CP_MAXMEM]
    return (
        iv[I_OUT] >= S[OUT_INT].shape[0]
        or iv[I_LAT] >= lat_cap
        or iv[I_LAT + 1] >= lat_cap
        or iv[I_LAT + 2] >= lat_cap
    )


@jit
def _limits(S, n):  # type: ignore[no-untyped-def]
    """Whether attempt draws come on demand, and the free slots an event may need
    (a fan-out, and its resend timers under QoS 1 over datagram)."""
    tp = S[TR_PARAMS]
    qos1d = tp[T_QOS1D]
    attempts = qos1d != 0 or tp[T_STREAM] != 0 or tp[T_STREAM + 1] != 0
    spare = n + 4 + qos1d * (n + 4)
    if S[CPU_IP][CP_SWITCH]:  # an outbox check sends up to OB_CAP messages at once
        spare += (2 + qos1d) * OB_CAP
    return attempts, spare


@jit
def _short(iv, spare):  # type: ignore[no-untyped-def]
    """Whether fewer than ``spare`` event slots or payload rows are free (Python grows
    them: an event may take a slot, and a payload row, for each copy it makes)."""
    return iv[I_FREE] < spare or iv[I_PFREE] < spare


@jit
def _drain_step(S, spare):  # type: ignore[no-untyped-def]
    """The draining stream connection's next segment: (code, slot, its event's time),
    slot -1 at the drain's end."""
    t = S[TR_FLOATS][0]
    if _short(S[INTS], spare):
        return NEED_SPACE, -1, t
    if _full(S):
        return NEED_FLUSH, -1, t
    return OK, next_ready(S), t


@jit
def _rows(S, s):  # type: ignore[no-untyped-def]
    """Start loading event slot ``s``'s rows."""
    prefetch(S[EV_INT], s)
    prefetch(S[EV_FLOAT], s)


@jit
def _ahead(S, ak, p, e):  # type: ignore[no-untyped-def]
    """Start loading what the current run's next events will read (the loop took position
    ``p`` of the run, which ends at ``e > p + 1``): the next event's slot rows and, its
    slot row having been asked for one event ago, what it reads besides (its payload
    row, the ring row a state reaching the server is stored in, the physics-ring row a
    job's state is published from); the rows of the event after it."""
    s = ak[p + 1] & SLOT_MASK
    _rows(S, s)
    if p + 2 >= e:
        return
    _rows(S, ak[p + 2] & SLOT_MASK)
    evi = S[EV_INT]
    r = evi[s, E_PAY] - 1
    if r >= 0:
        prefetch(S[POOL], r)
    typ = evi[s, E_TYPE]
    ip = S[IPARAMS]
    who = evi[s, E_WHO]
    if typ == EV_CLIENT and who == ip[Q_N] and ip[Q_RING]:
        subj = evi[s, E_SUBJ]
        slot = evi[s, E_FRAME] % S[RING_FRAME].shape[1]
        prefetch(S[RING_FRAME][subj], slot)
        prefetch(S[RING_GEN][subj], slot)
        prefetch(S[RING_OBS][subj], slot)
    elif typ == EV_DONE:
        prefetch(S[OBS_HIST][row_of(evi[s, E_INDEX], S[OBS_HIST].shape[0])], who)


@jit
def _handle(S, s, t):  # type: ignore[no-untyped-def]
    """Run event ``s``'s handler at ``t``, by its type."""
    typ = S[EV_INT][s, E_TYPE]
    if typ == EV_CLIENT:
        _client(S, s, t)
    elif typ == EV_BROKER:
        broker(S, s, t)
    elif typ == EV_RESEND:
        resend(S, s, t)
    elif typ == EV_DONE:
        done(S, s, t)
    elif typ == EV_SEND:
        if S[CPU_IP][CP_SWITCH]:
            burst_done(S, burst_copy(S, s), t)
        else:
            send_burst_done(S, s, t)
    elif typ == EV_LEAVE:
        leave(S, s, t)
    elif typ == EV_LOOP:
        loop_receive(S, s, t)
    elif typ == EV_NSEND:
        net_sent(S, s, t)
    else:
        hand_over(S, s, t, S[EV_FLOAT][s, EF_TRECV])  # EV_APP: the receive burst ended


@jit
def _run(S, s, t, c, p):  # type: ignore[no-untyped-def]
    """Run event ``s`` at ``t`` and free its slot; a fan-out batch or a channel's token
    (taken at arena row ``p`` of run ``c``) runs its head delivery or event and goes back
    to the queue with the rest (:mod:`~sigma_des.events.fast.fanout`,
    :mod:`~sigma_des.events.fast.channel`). Every event is tallied (``S.tally``: one by
    one or from a batch, its type and kind)."""
    evi = S[EV_INT]
    typ = evi[s, E_TYPE]
    tally = S[TALLY]
    if typ == EV_CHAN:
        e = chan_take(S, s)
        tally[1, evi[e, E_TYPE], evi[e, E_KIND]] += 1
        _handle(S, e, t)
        release(S, e)
        if chan_requeue(S, s, c, p):
            return
    elif typ == EV_BATCH:
        tally[1, EV_CLIENT, evi[s, E_KIND]] += 1
        head(S, s)
        _client(S, s, t)
        if requeue(S, s, c, p):
            return
    else:
        tally[0, typ, evi[s, E_KIND]] += 1
        _handle(S, s, t)
    release(S, s)


@jit
def advance(S, t_stop, strict):  # type: ignore[no-untyped-def]
    """Process message events up to ``t_stop`` (``< t_stop`` if ``strict``): OK when done, else
    the reason Python must act first. A draining stream's segments first, then the queue's head."""
    S = ref(S)  # handlers get one pointer, not the tuple by value (stateref)
    iv = S[INTS]
    n = S[IPARAMS][Q_N]
    Q = view(S)
    qi = S[Q_INT]
    at = S[RUN_T]
    ak = S[RUN_K]
    pos = S[RUN_POS]
    ht = S[HEAP_T]
    hk = S[HEAP_K]
    hr = S[HEAP_R]
    pmin = S[Q_FLOAT]
    attempts, spare = _limits(S, n)
    rp = S[RESIM_PEND]  # [n]: a node's re-simulation is owed (driver._rollback)
    while True:
        if S[TR_INTS][T_DRAIN]:  # a stream arrival hands its connection's segments on
            code, s, t = _drain_step(S, spare)
            c = p = -1  # not from a run (no batch drains: fanout.applies)
            if code != OK:
                return code
            if s < 0:
                continue
        else:
            c = qi[QI_CUR]
            p = 0
            t = 0.0
            due = qi[QI_HAS] != 0
            if due:
                p = pos[c]
                t = at[p]
                k = ak[p]
                nh = qi[QI_HEAP]
                if nh > 0 and precedes(ht[0], hk[0], t, k):  # the top run's turn
                    top = hr[0]
                    t = ht[0]
                    k = hk[0]
                    replace_top(ht, hk, hr, nh, at[p], ak[p], c)
                    c = top
                    qi[QI_CUR] = c
                    p = pos[c]
                due = qi[QI_PN] == 0 or precedes(t, k, pmin[QF_PMIN], qi[QI_PMINK])
            if not due:
                t = first(Q)
                if not qi[QI_HAS]:
                    break
                c = qi[QI_CUR]
                p = pos[c]
            if t > t_stop or (strict and t >= t_stop):
                return OK
            if _short(iv, spare):
                return NEED_SPACE
            if _full(S):
                return NEED_FLUSH
            s = ak[p] & SLOT_MASK  # the head
            if attempts and missing(S, s):
                return NEED_FILL
            if rp[n] != 0 and S[EV_INT][s, E_TYPE] == EV_DONE and rp[S[EV_INT][s, E_WHO]] != 0:
                return NEED_RESIM  # its publish reads rows whose re-simulation Python owes
            pos[c] = p + 1  # take the head
            e = S[RUN_END][c]
            if p + 1 == e:
                qi[QI_HAS] = 0
            else:  # a queued event's rows have rarely stayed in the cache: ask for them now
                _ahead(S, ak, p, e)
            if qi[QI_HEAP] > 0:  # the heap top's head is next if the run does not continue
                _rows(S, hk[0] & SLOT_MASK)
        _run(S, s, t, c, p)
        if iv[I_ERR]:
            return DRAW_MISS
        code = iv[I_PEND]
        if code:
            iv[I_PEND] = 0
            return code
    return OK
