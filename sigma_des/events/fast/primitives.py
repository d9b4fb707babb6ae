"""Layout and primitives of the cohort engine's compiled message core (numba).

All state of the core lives in one tuple ``S`` of numpy arrays; this module names
the positions in it (and in its scalar, parameter, node and event arrays) and holds
the primitives the handlers in :mod:`sigma_des.events.cohort_jit` build on: the
binary heap of ``(time, sequence)`` keys, the event-slot free list, the draw-table
lookup and one hop over an access link (FIFO serialization, latency, loss) — each
the same floating point operations, in the same order, as
:mod:`sigma_des.net.network`.
"""


from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from numba import njit

from sigma_des.net.kinds import Kind

_F = TypeVar("_F", bound=Callable[..., Any])

#: Compiled without numba's reference counting: every array is borrowed from the
#: driver and nothing is allocated, and NRT's atomic increments on each array access
#: made the loop ~4x slower.
jit: Callable[[_F], _F] = njit(cache=True, _nrt=False)  # type: ignore[call-overload]


# event types
EV_BROKER, EV_CLIENT, EV_DONE = 0, 1, 2
# exit codes of advance()
OK, NEED_START, NEED_ROLLBACK, NEED_FLUSH, NEED_SPACE, DRAW_MISS, BARRIER = 0, 1, 2, 3, 4, 5, 6

# message kinds, as plain ints for numba (declared once, in sigma_des.net.kinds)
K_TRIGGER, K_STATE, K_COMMAND, K_REREQ, K_REPUB = (int(k) for k in Kind)

# positions in the state tuple S
HT, HE, HS, EVI, EVF, FREE, II, FF, QQ, GG = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
LBUSY, LCNT, LSPB, LINK_OF = 10, 11, 12, 13
CMAP, CVAL, DVAL, DTAG, PLOSS, WB = 14, 15, 16, 17, 18, 19
ND, HOST_OF, CRASH, SLOW_PTR, SLOW, CORES = 20, 21, 22, 23, 24, 25
HLC_L, HLC_C, OFF, DRIFT = 26, 27, 28, 29
SLOT_FRAME, OBS_HIST, CMD = 30, 31, 32
OUT_I, OUT_F, LAT_BUF = 33, 34, 35
LAST_I, LAST_F, LS = 36, 37, 38
SEEN = 39  # Lock-Step: newest index seen per (re-request/republish, subject, index % H)
N_FIELDS = 40
# heap keys pack (sequence << SLOT_BITS) | event slot into one int64
SLOT_BITS = 24
SLOT_MASK = (1 << SLOT_BITS) - 1
MAX_SLOTS = 1 << SLOT_BITS

# int scalars S[II]
I_HEAP, I_EID, I_FREE, I_OUT, I_MSGS, I_HMISS, I_PEND, I_PNODE, I_PA, I_PB, I_NEV, I_ERR = range(12)
I_LAT = 12  # three counters: trigger, state, command latencies buffered
I_LCUR, I_LMISS, I_LCOMP = 15, 16, 17  # Lock-Step barrier mirror: frame, missing, complete
I_DUPS = 18  # duplicate deliveries (Collector.delivered's rule)
I_LEN = 19
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


@jit
def lat_source(cls: int, up: int) -> int:
    """Latency source of link class ``cls`` (0 host, 1 server) and direction ``up``."""
    return 2 * (1 - cls) + (1 - up)


# ---------------------------------------------------------------- heap and slots


@jit
def push(S, t, slot):  # type: ignore[no-untyped-def]
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


@jit
def pop(S):  # type: ignore[no-untyped-def]
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


@jit
def alloc(S):  # type: ignore[no-untyped-def]
    iv = S[II]
    iv[I_FREE] -= 1
    return S[FREE][iv[I_FREE]]


@jit
def release(S, slot):  # type: ignore[no-untyped-def]
    iv = S[II]
    S[FREE][iv[I_FREE]] = slot
    iv[I_FREE] += 1


# ---------------------------------------------------------------- draws and links


@jit
def draw(S, src, kind, subj, index):  # type: ignore[no-untyped-def]
    c = S[CMAP][src, kind]
    if c < 0:
        return S[CVAL][src]
    tag = S[DTAG]
    r = index % tag.shape[1]
    if tag[c, r] != index:
        S[II][I_ERR] = 1
        return 0.0
    return S[DVAL][c, r, subj]


@jit
def count(S, client, up, nbytes, t):  # type: ignore[no-untyped-def]
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


@jit
def hop(S, client, up, kind, subj, index, nbytes, t):  # type: ignore[no-untyped-def]
    """Network._hop: FIFO serialization + latency; returns (arrival, lost)."""
    done = count(S, client, up, nbytes, t)
    cls = 1 if client == S[QQ][Q_N] else 0
    src = lat_source(cls, up)
    lat = draw(S, src, kind, subj, index)
    p = S[PLOSS][cls]
    lost = False
    if p > 0.0:
        lost = draw(S, U_OFFSET + src, kind, subj, index) < p
    return done + lat, lost


@jit
def send_up(S, slot, client, kind, subject, index, t):  # type: ignore[no-untyped-def]
    """A PUBLISH (payload already in ``slot``) leaves ``client`` for the broker."""
    evi = S[EVI]
    evi[slot, E_TYPE] = EV_BROKER
    evi[slot, E_WHO] = client
    evi[slot, E_KIND] = kind
    evi[slot, E_SUBJ] = subject
    evi[slot, E_INDEX] = index
    arr, lost = hop(S, client, 1, kind, subject, index, S[WB][kind], t)
    if lost:
        release(S, slot)
    else:
        push(S, arr, slot)
