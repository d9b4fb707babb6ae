"""The alignment server's side of the compiled message core.

Every delivery is counted as :meth:`sigma_des.metrics.collector.Collector.delivered`
counts it (duplicates, messages, latencies, buffered for the collector); a state
reaching the server is stored in the aligner's ring buffers (BiDES: the rule of
:func:`~sigma_des.events.align.ring.insert_row`, in arrival order) or buffered for
its ``on_states`` (and for a recording tap), and under Lock-Step the
barrier's count is mirrored so the loop can stop when the barrier completes
(docs/concepts/methods.md).
"""

from __future__ import annotations

from sigma_des.events.align.ring import insert_row
from sigma_des.events.fast.codes import (
    BARRIER,
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_SUBJ,
    EF_GEN,
    EF_L,
    EF_TPUB,
    F_PT,
    G_WARMUP,
    I_DUPS,
    I_LAT,
    I_LCOMP,
    I_LCUR,
    I_LMISS,
    I_MSGS,
    I_OUT,
    I_PEND,
    K_REPUB,
    K_REREQ,
    Q_LOCK,
    Q_OUT,
    Q_RING,
    Q_W,
    T_DUPALL,
)
from sigma_des.events.fast.layout import (
    EV_FLOAT,
    EV_INT,
    FLOATS,
    FPARAMS,
    INTS,
    IPARAMS,
    LAT_BUF,
    LS_MIRROR,
    OUT_FLOAT,
    OUT_INT,
    POOL,
    RING_FRAME,
    RING_GEN,
    RING_LATEST,
    RING_OBS,
    SEEN,
    TR_PARAMS,
)
from sigma_des.events.fast.primitives import jit, payload, row_of

__all__ = ["at_server", "delivered"]


@jit
def delivered(S, s, now):  # type: ignore[no-untyped-def]
    """Collector.delivered for one arrival: duplicates, message count, latency."""
    evi = S[EV_INT]
    iv = S[INTS]
    kind = evi[s, E_KIND]
    index = evi[s, E_INDEX]
    t_pub = S[EV_FLOAT][s, EF_TPUB]
    # Collector.delivered: without QoS 1 over datagram only a re-request or republished
    # state can come twice (a retry index is capped: sigma_des.net.kinds.rerequest_index);
    # with it, a resend makes any kind a possible duplicate (one seen row per kind)
    dup = False
    dup_all = S[TR_PARAMS][T_DUPALL]
    if dup_all or kind >= K_REREQ:
        seen = S[SEEN]
        row = kind if dup_all else kind - K_REREQ
        subject = evi[s, E_SUBJ]
        slot = row_of(index, seen.shape[2])
        if seen[row, subject, slot] == index:
            dup = True
            iv[I_DUPS] += 1
        else:
            seen[row, subject, slot] = index
    if not dup and t_pub >= S[FPARAMS][G_WARMUP]:
        iv[I_MSGS] += 1
        if kind != K_REREQ:  # a republished state's latency counts as a state's
            lk = 1 if kind == K_REPUB else kind - 1
            S[LAT_BUF][lk, iv[I_LAT + lk]] = now - t_pub
            iv[I_LAT + lk] += 1


@jit
def _barrier(S, subject, frame, now):  # type: ignore[no-untyped-def]
    """LockstepAligner.on_states' barrier count, mirrored."""
    iv = S[INTS]
    ls = S[LS_MIRROR]
    if ls[1, subject] == 0 and frame == iv[I_LCUR]:
        ls[1, subject] = 1
        iv[I_LMISS] += 1
    if frame == iv[I_LCUR] and iv[I_LCOMP] == 0 and ls[0, subject] == 0:
        iv[I_LMISS] -= 1
        ls[0, subject] = 1
        if iv[I_LMISS] <= 0:
            iv[I_LCOMP] = 1
            iv[I_PEND] = BARRIER
            S[FLOATS][F_PT] = now


@jit
def at_server(S, s, now):  # type: ignore[no-untyped-def]
    """A (re)published state reaches the server: stored in the aligner's ring (Q_RING),
    buffered for Python (Q_OUT), counted for the Lock-Step barrier (Q_LOCK)."""
    evi = S[EV_INT]
    ip = S[IPARAMS]
    subject = evi[s, E_SUBJ]
    frame = evi[s, E_FRAME]
    gen = S[EV_FLOAT][s, EF_GEN]
    pool = S[POOL]
    r = payload(S, s)
    if ip[Q_RING]:  # BidesAligner.on_states, row by row: RingBuffers.insert's rule
        insert_row(S[RING_FRAME], S[RING_GEN], S[RING_OBS], S[RING_LATEST], subject, frame,
                   gen, pool, r)
    if ip[Q_OUT]:
        iv = S[INTS]
        o = iv[I_OUT]
        iv[I_OUT] = o + 1
        oi = S[OUT_INT]
        of = S[OUT_FLOAT]
        oi[o, 0] = subject
        oi[o, 1] = frame
        oi[o, 2] = evi[s, E_AUX]
        of[o, 0] = now
        of[o, 1] = gen
        of[o, 2] = S[EV_FLOAT][s, EF_L]
        for j in range(ip[Q_W]):
            of[o, 3 + j] = pool[r, j]
    if ip[Q_LOCK]:
        _barrier(S, subject, frame, now)
