"""Compiled message core of the cohort engine (numba).

The per-message engine (:mod:`sigma_des.events.engine` over
:mod:`sigma_des.net.network`) is the executable specification. This module runs
the same message model — access-link FIFOs, the broker's FIFO (the Lindley
recursion, one departure after another), host cores, node triggers, state
publishes and command deliveries — as a compiled loop over a binary heap of
``(time, sequence)`` keys held in numpy arrays. It performs the same floating
point operations in the same order as the specification and numbers events in
the same relative order, so simultaneous events are broken the same way and the
results are bit-identical.

All state lives in one tuple ``S`` of numpy arrays (its layout and the heap, slot,
draw and link primitives are in :mod:`sigma_des.events.cohort_state`), shared with
the Python driver (:mod:`sigma_des.events.cohort`). The loop hands control back
to Python, between two events, when something needs Python: a time-warp rollback
(re-simulating physics), a job whose cost includes rollback draws, a full
delivery buffer, a full event table, or a random draw that is not in the draw
tables (then the driver falls back to the per-message engine).

Random numbers are never drawn here: Python fills per-index rows of the draw
tables (``dval``) from the very same counter-based samplers the specification
uses, and this loop reads them.
"""

from __future__ import annotations

from sigma_des.events.cohort_state import (
    BARRIER,
    CMD,
    CORES,
    CRASH,
    DRAW_MISS,
    DRIFT,
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_SUBJ,
    E_TYPE,
    E_WHO,
    EF_GEN,
    EF_L,
    EF_PAY,
    EF_TDEP,
    EF_TPUB,
    EV_BROKER,
    EV_CLIENT,
    EV_DONE,
    EVF,
    EVI,
    F_BUSY,
    F_MAXWAIT,
    F_PT,
    F_WORK,
    FF,
    G_END,
    G_WARMUP,
    GG,
    HLC_C,
    HLC_L,
    HOST_OF,
    HT,
    I_DUPS,
    I_ERR,
    I_FREE,
    I_HEAP,
    I_HMISS,
    I_LAT,
    I_LCOMP,
    I_LCUR,
    I_LMISS,
    I_MSGS,
    I_OUT,
    I_PA,
    I_PB,
    I_PEND,
    I_PNODE,
    II,
    K_COMMAND,
    K_REPUB,
    K_REREQ,
    K_STATE,
    K_TRIGGER,
    LAST_F,
    LAST_I,
    LAT_BUF,
    LS,
    N_BUSY,
    N_CSTAMP,
    N_FRAME,
    N_RB,
    N_REQ,
    N_TARGET,
    ND,
    NEED_FLUSH,
    NEED_ROLLBACK,
    NEED_SPACE,
    NEED_START,
    OBS_HIST,
    OFF,
    OK,
    OUT_F,
    OUT_I,
    Q_ACK,
    Q_HLC,
    Q_LOCK,
    Q_M,
    Q_N,
    Q_QOS1S,
    Q_THETA,
    Q_W,
    Q_WARP,
    QQ,
    SEEN,
    SLOT_FRAME,
    SLOW,
    SLOW_PTR,
    STEP,
    SVC_DEL,
    SVC_PUB,
    WB,
    alloc,
    count,
    draw,
    hop,
    jit,
    pop,
    push,
    release,
    send_up,
)

__all__ = [
    "advance",
    "publish_commands",
    "publish_rerequest",
    "publish_trigger",
    "reserve",
]


# ---------------------------------------------------------------- broker


@jit
def _deliver_try(S, src, sub, kind, dsubj, index, d):  # type: ignore[no-untyped-def]
    slot = alloc(S)
    evf = S[EVF]
    evi = S[EVI]
    for j in range(evf.shape[1]):
        evf[slot, j] = evf[src, j]
    evf[slot, EF_TDEP] = d
    evi[slot, E_TYPE] = EV_CLIENT
    evi[slot, E_WHO] = sub
    evi[slot, E_KIND] = kind
    evi[slot, E_SUBJ] = dsubj
    evi[slot, E_INDEX] = index
    evi[slot, E_AUX] = evi[src, E_AUX]
    evi[slot, E_FRAME] = evi[src, E_FRAME]
    arr, lost = hop(S, sub, 0, kind, dsubj, index, S[WB][kind], d)
    if lost:
        release(S, slot)
    else:
        push(S, arr, slot)


@jit
def _work(S, a, b):  # type: ignore[no-untyped-def]
    g = S[GG]
    lo = a if a > g[G_WARMUP] else g[G_WARMUP]
    hi = b if b < g[G_END] else g[G_END]
    if hi > lo:
        S[FF][F_WORK] += hi - lo


@jit
def _broker(S, s, now):  # type: ignore[no-untyped-def]
    evi = S[EVI]
    ff = S[FF]
    g = S[GG]
    q = S[QQ]
    n = q[Q_N]
    client = evi[s, E_WHO]
    kind = evi[s, E_KIND]
    subject = evi[s, E_SUBJ]
    index = evi[s, E_INDEX]
    s_pub = draw(S, SVC_PUB, kind, subject, index)
    busy = ff[F_BUSY]
    start = now if now > busy else busy
    if g[G_WARMUP] <= now and now < g[G_END]:
        ff[F_MAXWAIT] = max(ff[F_MAXWAIT], start - now)
    if q[Q_QOS1S]:
        count(S, client, 0, q[Q_ACK], start + s_pub)
    d = start + s_pub
    if subject == n:  # a broadcast: one delivery per node, keyed by the subscriber
        for sub in range(n):
            d += draw(S, SVC_DEL, kind, sub, index)
            _deliver_try(S, s, sub, kind, sub, index, d)
    else:
        sub = n if kind == K_STATE or kind == K_REPUB else subject
        d += draw(S, SVC_DEL, kind, subject, index)
        _deliver_try(S, s, sub, kind, subject, index, d)
    ff[F_BUSY] = d
    _work(S, start, d)


# ---------------------------------------------------------------- nodes


@jit
def _local(S, i, t):  # type: ignore[no-untyped-def]
    return t + S[OFF][i] + S[DRIFT][i] * t


@jit
def reserve(S, i, target, cost, now):  # type: ignore[no-untyped-def]
    """Take the host's earliest-free core for ``cost`` seconds; schedule completion."""
    row = S[CORES][S[HOST_OF][i]]
    m = 0
    for j in range(1, row.shape[0]):
        if row[j] < row[m]:
            m = j
    free = row[m]
    start = now if now > free else free
    row[m] = start + cost
    nd = S[ND]
    nd[N_BUSY, i] = 1
    nd[N_TARGET, i] = target
    slot = alloc(S)
    evi = S[EVI]
    evi[slot, E_TYPE] = EV_DONE
    evi[slot, E_WHO] = i
    evi[slot, E_INDEX] = target
    push(S, start + cost, slot)


@jit
def _start_job(S, i, now):  # type: ignore[no-untyped-def]
    nd = S[ND]
    if nd[N_RB, i] != 0:  # rollback draws are Python's: hand the start over
        iv = S[II]
        iv[I_PEND] = NEED_START
        iv[I_PNODE] = i
        S[FF][F_PT] = now
        return
    target = nd[N_REQ, i]
    cost = 0.0
    for f in range(nd[N_FRAME, i] + 1, target + 1):
        cost += draw(S, STEP, 0, i, f)
    ptr = S[SLOW_PTR]
    slow = S[SLOW]
    for j in range(ptr[i], ptr[i + 1]):
        if slow[j, 0] <= now and now < slow[j, 1]:
            cost *= slow[j, 2]
    reserve(S, i, target, cost, now)


@jit
def _done(S, s, now):  # type: ignore[no-untyped-def]
    nd = S[ND]
    i = S[EVI][s, E_WHO]
    target = S[EVI][s, E_INDEX]
    nd[N_BUSY, i] = 0
    if now >= S[CRASH][i]:
        return
    if target > nd[N_FRAME, i]:
        nd[N_FRAME, i] = target
        h = S[SLOT_FRAME].shape[0]
        sl = target % h
        if S[SLOT_FRAME][sl] != target:
            S[II][I_HMISS] += 1
        ns = alloc(S)
        evf = S[EVF]
        w = S[QQ][Q_W]
        evf[ns, EF_TPUB] = now
        evf[ns, EF_GEN] = now
        oh = S[OBS_HIST]
        for j in range(w):
            evf[ns, EF_PAY + j] = oh[sl, i, j]
        if S[QQ][Q_HLC]:
            pt = _local(S, i, now)
            hl = S[HLC_L]
            old = hl[i]
            new = pt if pt > old else old
            S[HLC_C][i] = S[HLC_C][i] + 1 if new == old else 0
            hl[i] = new
            evf[ns, EF_L] = new
            S[EVI][ns, E_AUX] = S[HLC_C][i]
        S[EVI][ns, E_FRAME] = target
        if S[QQ][Q_LOCK]:  # kept for re-requests (MethodRun.last_pub)
            li = S[LAST_I]
            lf = S[LAST_F]
            li[i, 0] = target
            li[i, 1] = S[EVI][ns, E_AUX]
            lf[i, 0] = now
            lf[i, 1] = evf[ns, EF_L]
            for j in range(w):
                lf[i, 2 + j] = evf[ns, EF_PAY + j]
        send_up(S, ns, i, K_STATE, i, target, now)
    if nd[N_REQ, i] > nd[N_FRAME, i] or nd[N_RB, i] != 0:
        _start_job(S, i, now)


@jit
def _delivered(S, s, now):  # type: ignore[no-untyped-def]
    """Collector.delivered for one arrival: duplicates, message count, latency."""
    evi = S[EVI]
    iv = S[II]
    kind = evi[s, E_KIND]
    subject = evi[s, E_SUBJ]
    index = evi[s, E_INDEX]
    t_pub = S[EVF][s, EF_TPUB]
    # Collector.delivered: on this path only a re-request or republished state can come
    # twice (a retry index is capped at 63: frame * 64 + min(retry, 63))
    dup = False
    if kind >= K_REREQ:
        seen = S[SEEN]
        row = kind - K_REREQ
        slot = index % seen.shape[2]
        if seen[row, subject, slot] == index:
            dup = True
            iv[I_DUPS] += 1
        else:
            seen[row, subject, slot] = index
    if not dup and t_pub >= S[GG][G_WARMUP]:
        iv[I_MSGS] += 1
        if kind != K_REREQ:  # a republished state's latency counts as a state's
            lk = 1 if kind == K_REPUB else kind - 1
            S[LAT_BUF][lk, iv[I_LAT + lk]] = now - t_pub
            iv[I_LAT + lk] += 1


@jit
def _at_server(S, s, now):  # type: ignore[no-untyped-def]
    """A (re)published state reaches the server: buffer it for the aligner."""
    evi = S[EVI]
    evf = S[EVF]
    q = S[QQ]
    iv = S[II]
    subject = evi[s, E_SUBJ]
    o = iv[I_OUT]
    iv[I_OUT] = o + 1
    oi = S[OUT_I]
    of = S[OUT_F]
    frame = evi[s, E_FRAME]
    oi[o, 0] = subject
    oi[o, 1] = frame
    oi[o, 2] = evi[s, E_AUX]
    of[o, 0] = now
    of[o, 1] = evf[s, EF_GEN]
    of[o, 2] = evf[s, EF_L]
    w = q[Q_W]
    for j in range(w):
        of[o, 3 + j] = evf[s, EF_PAY + j]
    if q[Q_LOCK]:  # LockstepAligner.on_states' barrier count, mirrored
        ls = S[LS]
        if ls[1, subject] == 0 and frame == iv[I_LCUR]:
            ls[1, subject] = 1
            iv[I_LMISS] += 1
        if frame == iv[I_LCUR] and iv[I_LCOMP] == 0 and ls[0, subject] == 0:
            iv[I_LMISS] -= 1
            ls[0, subject] = 1
            if iv[I_LMISS] <= 0:
                iv[I_LCOMP] = 1
                iv[I_PEND] = BARRIER
                S[FF][F_PT] = now


@jit
def _at_node(S, s, now):  # type: ignore[no-untyped-def]
    """A trigger, re-request or command reaches its (live) node."""
    evi = S[EVI]
    evf = S[EVF]
    q = S[QQ]
    iv = S[II]
    sub = evi[s, E_WHO]
    kind = evi[s, E_KIND]
    index = evi[s, E_INDEX]
    if now >= S[CRASH][sub]:
        return
    nd = S[ND]
    if kind == K_TRIGGER:
        if q[Q_HLC]:
            pt = _local(S, sub, now)
            ml = evf[s, EF_L]
            mc = evi[s, E_AUX]
            hl = S[HLC_L]
            hc = S[HLC_C]
            old = hl[sub]
            new = old
            if ml > new:
                new = ml
            if pt > new:
                new = pt
            if new == old and new == ml:
                hc[sub] = max(hc[sub], mc) + 1
            elif new == old:
                hc[sub] += 1
            elif new == ml:
                hc[sub] = mc + 1
            else:
                hc[sub] = 0
            hl[sub] = new
        if index > nd[N_REQ, sub]:
            nd[N_REQ, sub] = index
            if nd[N_BUSY, sub] == 0:
                _start_job(S, sub, now)
    elif kind == K_REREQ:
        frame = evi[s, E_FRAME]
        li = S[LAST_I]
        if nd[N_FRAME, sub] >= frame and li[sub, 0] == frame:
            ns = alloc(S)
            lf = S[LAST_F]
            evf[ns, EF_TPUB] = now
            evf[ns, EF_GEN] = lf[sub, 0]
            evf[ns, EF_L] = lf[sub, 1]
            for j in range(q[Q_W]):
                evf[ns, EF_PAY + j] = lf[sub, 2 + j]
            evi[ns, E_AUX] = li[sub, 1]
            evi[ns, E_FRAME] = frame
            send_up(S, ns, sub, K_REPUB, sub, index, now)
        elif nd[N_REQ, sub] < frame:
            nd[N_REQ, sub] = frame
            if nd[N_BUSY, sub] == 0:
                _start_job(S, sub, now)
    elif kind == K_COMMAND:
        stamp = evi[s, E_AUX]
        if stamp < nd[N_CSTAMP, sub]:
            return  # an older command overtaken by a newer one
        nd[N_CSTAMP, sub] = stamp
        m = q[Q_M]
        cmd = S[CMD]
        for j in range(m):
            cmd[sub, j] = evf[s, EF_PAY + j]
        if not q[Q_WARP] or stamp < 0:
            return
        current = nd[N_TARGET, sub] if nd[N_BUSY, sub] else nd[N_FRAME, sub]
        if current - stamp <= q[Q_THETA]:
            return
        iv[I_PEND] = NEED_ROLLBACK
        iv[I_PNODE] = sub
        iv[I_PA] = stamp
        iv[I_PB] = current
        S[FF][F_PT] = now


@jit
def _client(S, s, now):  # type: ignore[no-untyped-def]
    """A delivery reaches its subscriber (Network._client_receive + deliver)."""
    q = S[QQ]
    sub = S[EVI][s, E_WHO]
    if q[Q_QOS1S]:
        count(S, sub, 1, q[Q_ACK], now)
    _delivered(S, s, now)
    if sub == q[Q_N]:
        _at_server(S, s, now)
    else:
        _at_node(S, s, now)


# ---------------------------------------------------------------- entry points


@jit
def publish_trigger(S, k, t, hlc_l, hlc_c):  # type: ignore[no-untyped-def]
    """The server publishes trigger ``k`` at ``t`` (with its HLC stamp)."""
    ns = alloc(S)
    S[EVF][ns, EF_TPUB] = t
    S[EVF][ns, EF_L] = hlc_l
    S[EVI][ns, E_AUX] = hlc_c
    n = S[QQ][Q_N]
    send_up(S, ns, n, K_TRIGGER, n, k, t)


@jit
def publish_commands(S, tick, stamp, nodes, rows, t):  # type: ignore[no-untyped-def]
    """The server publishes ``rows[i]`` to each node ``i`` of ``nodes``, in order."""
    n = S[QQ][Q_N]
    m = S[QQ][Q_M]
    for i in nodes:
        ns = alloc(S)
        S[EVF][ns, EF_TPUB] = t
        for j in range(m):
            S[EVF][ns, EF_PAY + j] = rows[i, j]
        S[EVI][ns, E_AUX] = stamp
        send_up(S, ns, n, K_COMMAND, i, tick, t)


@jit
def publish_rerequest(S, node, frame, index, t):  # type: ignore[no-untyped-def]
    """Lock-Step: the server asks ``node`` again for its state of ``frame``."""
    ns = alloc(S)
    S[EVF][ns, EF_TPUB] = t
    S[EVI][ns, E_FRAME] = frame
    send_up(S, ns, S[QQ][Q_N], K_REREQ, node, index, t)


@jit
def advance(S, t_stop, strict):  # type: ignore[no-untyped-def]
    """Process message events up to ``t_stop`` (``< t_stop`` if ``strict``).

    Returns:
        OK when done, else the reason Python must act before the next event.
    """
    iv = S[II]
    ht = S[HT]
    n = S[QQ][Q_N]
    out_cap = S[OUT_I].shape[0]
    lat_cap = S[LAT_BUF].shape[1]
    while iv[I_HEAP] > 0:
        t = ht[0]
        if t > t_stop or (strict and t >= t_stop):
            return OK
        if iv[I_FREE] < n + 4:
            return NEED_SPACE
        if (
            iv[I_OUT] >= out_cap
            or iv[I_LAT] >= lat_cap
            or iv[I_LAT + 1] >= lat_cap
            or iv[I_LAT + 2] >= lat_cap
        ):
            return NEED_FLUSH
        s = pop(S)
        typ = S[EVI][s, E_TYPE]
        if typ == EV_CLIENT:
            _client(S, s, t)
        elif typ == EV_BROKER:
            _broker(S, s, t)
        else:
            _done(S, s, t)
        release(S, s)
        if iv[I_ERR]:
            return DRAW_MISS
        if iv[I_PEND]:
            code = iv[I_PEND]
            iv[I_PEND] = 0
            return code
    return OK

