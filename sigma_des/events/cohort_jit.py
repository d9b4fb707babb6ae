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

All state lives in one tuple ``S`` of numpy arrays (positions below), shared with
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

from collections.abc import Callable
from typing import Any, TypeVar

from numba import njit

_F = TypeVar("_F", bound=Callable[..., Any])

#: Compiled without numba's reference counting: every array is borrowed from the
#: driver and nothing is allocated, and NRT's atomic increments on each array access
#: made the loop ~4x slower.
_jit: Callable[[_F], _F] = njit(cache=True, _nrt=False)  # type: ignore[call-overload]

__all__ = [
    "advance",
    "publish_commands",
    "publish_rerequest",
    "publish_trigger",
    "reserve",
]

# event types
EV_BROKER, EV_CLIENT, EV_DONE = 0, 1, 2
# exit codes of advance()
OK, NEED_START, NEED_ROLLBACK, NEED_FLUSH, NEED_SPACE, DRAW_MISS, BARRIER = 0, 1, 2, 3, 4, 5, 6

# message kinds (as in sigma_des.net.network)
K_TRIGGER, K_STATE, K_COMMAND, K_REREQ, K_REPUB = 1, 2, 3, 4, 5

# positions in the state tuple S
HT, HE, HS, EVI, EVF, FREE, II, FF, QQ, GG = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
LBUSY, LCNT, LSPB, LINK_OF = 10, 11, 12, 13
CMAP, CVAL, DVAL, DTAG, PLOSS, WB = 14, 15, 16, 17, 18, 19
ND, HOST_OF, CRASH, SLOW_PTR, SLOW, CORES = 20, 21, 22, 23, 24, 25
HLC_L, HLC_C, OFF, DRIFT = 26, 27, 28, 29
SLOT_FRAME, OBS_HIST, CMD = 30, 31, 32
OUT_I, OUT_F, LAT_BUF = 33, 34, 35
LAST_I, LAST_F, LS = 36, 37, 38
N_FIELDS = 39
# heap keys pack (sequence << SLOT_BITS) | event slot into one int64
SLOT_BITS = 24
SLOT_MASK = (1 << SLOT_BITS) - 1
MAX_SLOTS = 1 << SLOT_BITS

# int scalars S[II]
I_HEAP, I_EID, I_FREE, I_OUT, I_MSGS, I_HMISS, I_PEND, I_PNODE, I_PA, I_PB, I_NEV, I_ERR = range(12)
I_LAT = 12  # three counters: trigger, state, command latencies buffered
I_LCUR, I_LMISS, I_LCOMP = 15, 16, 17  # Lock-Step barrier mirror: frame, missing, complete
I_LEN = 18
# float scalars S[FF]
F_BUSY, F_WORK, F_MAXWAIT, F_PT = range(4)
F_LEN = 4
# int parameters S[QQ]
Q_N, Q_H, Q_HLC, Q_WARP, Q_THETA, Q_QOS1S, Q_ACK, Q_W, Q_M, Q_LOCK = range(10)
Q_LEN = 10
# float parameters S[GG]
G_WARMUP, G_END = 0, 1
G_LEN = 2
# node integer rows S[ND]
N_FRAME, N_REQ, N_TARGET, N_BUSY, N_RB, N_CSTAMP = range(6)
N_ROWS = 6
# event int columns S[EVI]: type, client/receiver, kind, subject, index, aux (HLC c or
# command stamp), frame (of a state, republished state or re-request)
E_TYPE, E_WHO, E_KIND, E_SUBJ, E_INDEX, E_AUX, E_FRAME = range(7)
E_COLS = 7
# event float columns S[EVF]: t_publish, t_depart, HLC l, generation time, payload...
EF_TPUB, EF_TDEP, EF_L, EF_GEN, EF_PAY = range(5)
# draw sources: latency and loss uniforms per (link class, direction), broker, compute
LAT_SU, LAT_SD, LAT_HU, LAT_HD = 0, 1, 2, 3
U_OFFSET = 4
SVC_PUB, SVC_DEL, STEP = 8, 9, 10
N_SOURCES = 11


@_jit
def lat_source(cls: int, up: int) -> int:
    """Latency source of link class ``cls`` (0 host, 1 server) and direction ``up``."""
    return 2 * (1 - cls) + (1 - up)


# ---------------------------------------------------------------- heap and slots


@_jit
def _push(S, t, slot):  # type: ignore[no-untyped-def]
    ht = S[HT]
    hk = S[HE]
    iv = S[II]
    e = iv[I_EID]
    iv[I_EID] = e + 1
    iv[I_NEV] += 1
    key = (e << SLOT_BITS) | slot  # sequence number first: it alone orders equal times
    i = iv[I_HEAP]
    iv[I_HEAP] = i + 1
    while i > 0:
        p = (i - 1) >> 1
        if t < ht[p] or (t == ht[p] and key < hk[p]):
            ht[i] = ht[p]
            hk[i] = hk[p]
            i = p
        else:
            break
    ht[i] = t
    hk[i] = key


@_jit
def _pop(S):  # type: ignore[no-untyped-def]
    ht = S[HT]
    hk = S[HE]
    iv = S[II]
    n = iv[I_HEAP] - 1
    iv[I_HEAP] = n
    top = hk[0] & SLOT_MASK
    if n > 0:
        t = ht[n]
        key = hk[n]
        i = 0
        while True:
            c = 2 * i + 1
            if c >= n:
                break
            if c + 1 < n and (ht[c + 1] < ht[c] or (ht[c + 1] == ht[c] and hk[c + 1] < hk[c])):
                c += 1
            if ht[c] < t or (ht[c] == t and hk[c] < key):
                ht[i] = ht[c]
                hk[i] = hk[c]
                i = c
            else:
                break
        ht[i] = t
        hk[i] = key
    return top


@_jit
def _alloc(S):  # type: ignore[no-untyped-def]
    iv = S[II]
    iv[I_FREE] -= 1
    return S[FREE][iv[I_FREE]]


@_jit
def _release(S, slot):  # type: ignore[no-untyped-def]
    iv = S[II]
    S[FREE][iv[I_FREE]] = slot
    iv[I_FREE] += 1


# ---------------------------------------------------------------- draws and links


@_jit
def _draw(S, src, kind, subj, index):  # type: ignore[no-untyped-def]
    c = S[CMAP][src, kind]
    if c < 0:
        return S[CVAL][src]
    tag = S[DTAG]
    r = index % tag.shape[1]
    if tag[c, r] != index:
        S[II][I_ERR] = 1
        return 0.0
    return S[DVAL][c, r, subj]


@_jit
def _count(S, client, up, nbytes, t):  # type: ignore[no-untyped-def]
    """Network._count: FIFO serialization on the client's link, counted in the window.

    Returns:
        The time the last bit leaves.
    """
    link = S[LINK_OF][client]
    lb = S[LBUSY]
    busy = lb[up, link]
    done = (t if t > busy else busy) + nbytes * S[LSPB][up, link]
    lb[up, link] = done
    g = S[GG]
    if g[G_WARMUP] <= t and t < g[G_END]:
        S[LCNT][up, 0, link] += nbytes
        S[LCNT][up, 1, link] += 1
    return done


@_jit
def _hop(S, client, up, kind, subj, index, nbytes, t):  # type: ignore[no-untyped-def]
    """Network._hop: FIFO serialization + latency; returns (arrival, lost)."""
    done = _count(S, client, up, nbytes, t)
    cls = 1 if client == S[QQ][Q_N] else 0
    src = lat_source(cls, up)
    lat = _draw(S, src, kind, subj, index)
    p = S[PLOSS][cls]
    lost = False
    if p > 0.0:
        lost = _draw(S, U_OFFSET + src, kind, subj, index) < p
    return done + lat, lost


@_jit
def _send_up(S, slot, client, kind, subject, index, t):  # type: ignore[no-untyped-def]
    """A PUBLISH (payload already in ``slot``) leaves ``client`` for the broker."""
    evi = S[EVI]
    evi[slot, E_TYPE] = EV_BROKER
    evi[slot, E_WHO] = client
    evi[slot, E_KIND] = kind
    evi[slot, E_SUBJ] = subject
    evi[slot, E_INDEX] = index
    arr, lost = _hop(S, client, 1, kind, subject, index, S[WB][kind], t)
    if lost:
        _release(S, slot)
    else:
        _push(S, arr, slot)


# ---------------------------------------------------------------- broker


@_jit
def _deliver_try(S, src, sub, kind, dsubj, index, d):  # type: ignore[no-untyped-def]
    slot = _alloc(S)
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
    arr, lost = _hop(S, sub, 0, kind, dsubj, index, S[WB][kind], d)
    if lost:
        _release(S, slot)
    else:
        _push(S, arr, slot)


@_jit
def _work(S, a, b):  # type: ignore[no-untyped-def]
    g = S[GG]
    lo = a if a > g[G_WARMUP] else g[G_WARMUP]
    hi = b if b < g[G_END] else g[G_END]
    if hi > lo:
        S[FF][F_WORK] += hi - lo


@_jit
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
    s_pub = _draw(S, SVC_PUB, kind, subject, index)
    busy = ff[F_BUSY]
    start = now if now > busy else busy
    if g[G_WARMUP] <= now and now < g[G_END]:
        ff[F_MAXWAIT] = max(ff[F_MAXWAIT], start - now)
    if q[Q_QOS1S]:
        _count(S, client, 0, q[Q_ACK], start + s_pub)
    d = start + s_pub
    if subject == n:  # a broadcast: one delivery per node, keyed by the subscriber
        for sub in range(n):
            d += _draw(S, SVC_DEL, kind, sub, index)
            _deliver_try(S, s, sub, kind, sub, index, d)
    else:
        sub = n if kind == K_STATE or kind == K_REPUB else subject
        d += _draw(S, SVC_DEL, kind, subject, index)
        _deliver_try(S, s, sub, kind, subject, index, d)
    ff[F_BUSY] = d
    _work(S, start, d)


# ---------------------------------------------------------------- nodes


@_jit
def _local(S, i, t):  # type: ignore[no-untyped-def]
    return t + S[OFF][i] + S[DRIFT][i] * t


@_jit
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
    slot = _alloc(S)
    evi = S[EVI]
    evi[slot, E_TYPE] = EV_DONE
    evi[slot, E_WHO] = i
    evi[slot, E_INDEX] = target
    _push(S, start + cost, slot)


@_jit
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
        cost += _draw(S, STEP, 0, i, f)
    ptr = S[SLOW_PTR]
    slow = S[SLOW]
    for j in range(ptr[i], ptr[i + 1]):
        if slow[j, 0] <= now and now < slow[j, 1]:
            cost *= slow[j, 2]
    reserve(S, i, target, cost, now)


@_jit
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
        ns = _alloc(S)
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
        _send_up(S, ns, i, K_STATE, i, target, now)
    if nd[N_REQ, i] > nd[N_FRAME, i] or nd[N_RB, i] != 0:
        _start_job(S, i, now)


@_jit
def _client(S, s, now):  # type: ignore[no-untyped-def]
    evi = S[EVI]
    evf = S[EVF]
    q = S[QQ]
    iv = S[II]
    n = q[Q_N]
    sub = evi[s, E_WHO]
    kind = evi[s, E_KIND]
    subject = evi[s, E_SUBJ]
    index = evi[s, E_INDEX]
    t_pub = evf[s, EF_TPUB]
    if q[Q_QOS1S]:
        _count(S, sub, 1, q[Q_ACK], now)
    if t_pub >= S[GG][G_WARMUP]:  # Collector.delivered (no duplicates on this path)
        iv[I_MSGS] += 1
        if kind != K_REREQ:  # a republished state's latency counts as a state's
            lk = 1 if kind == K_REPUB else kind - 1
            S[LAT_BUF][lk, iv[I_LAT + lk]] = now - t_pub
            iv[I_LAT + lk] += 1
    if sub == n:
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
        if q[Q_LOCK]:  # LockstepAligner.on_state's barrier count, mirrored
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
        return
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
            ns = _alloc(S)
            lf = S[LAST_F]
            evf[ns, EF_TPUB] = now
            evf[ns, EF_GEN] = lf[sub, 0]
            evf[ns, EF_L] = lf[sub, 1]
            for j in range(q[Q_W]):
                evf[ns, EF_PAY + j] = lf[sub, 2 + j]
            evi[ns, E_AUX] = li[sub, 1]
            evi[ns, E_FRAME] = frame
            _send_up(S, ns, sub, K_REPUB, sub, index, now)
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


# ---------------------------------------------------------------- entry points


@_jit
def publish_trigger(S, k, t, hlc_l, hlc_c):  # type: ignore[no-untyped-def]
    """The server publishes trigger ``k`` at ``t`` (with its HLC stamp)."""
    ns = _alloc(S)
    S[EVF][ns, EF_TPUB] = t
    S[EVF][ns, EF_L] = hlc_l
    S[EVI][ns, E_AUX] = hlc_c
    n = S[QQ][Q_N]
    _send_up(S, ns, n, K_TRIGGER, n, k, t)


@_jit
def publish_commands(S, tick, stamp, nodes, rows, t):  # type: ignore[no-untyped-def]
    """The server publishes ``rows[i]`` to each node ``i`` of ``nodes``, in order."""
    n = S[QQ][Q_N]
    m = S[QQ][Q_M]
    for i in nodes:
        ns = _alloc(S)
        S[EVF][ns, EF_TPUB] = t
        for j in range(m):
            S[EVF][ns, EF_PAY + j] = rows[i, j]
        S[EVI][ns, E_AUX] = stamp
        _send_up(S, ns, n, K_COMMAND, i, tick, t)


@_jit
def publish_rerequest(S, node, frame, index, t):  # type: ignore[no-untyped-def]
    """Lock-Step: the server asks ``node`` again for its state of ``frame``."""
    ns = _alloc(S)
    S[EVF][ns, EF_TPUB] = t
    S[EVI][ns, E_FRAME] = frame
    _send_up(S, ns, S[QQ][Q_N], K_REREQ, node, index, t)


@_jit
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
        s = _pop(S)
        typ = S[EVI][s, E_TYPE]
        if typ == EV_CLIENT:
            _client(S, s, t)
        elif typ == EV_BROKER:
            _broker(S, s, t)
        else:
            _done(S, s, t)
        _release(S, s)
        if iv[I_ERR]:
            return DRAW_MISS
        if iv[I_PEND]:
            code = iv[I_PEND]
            iv[I_PEND] = 0
            return code
    return OK

