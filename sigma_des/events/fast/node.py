"""Physics nodes in the compiled message core (docs/concepts/model.md, "Physics nodes").

A node takes triggers, re-requests and commands; it computes a job on its host's
earliest-free core (:mod:`~sigma_des.events.fast.job`: the job's cost, rollback draws
included, as :func:`sigma_des.events.jobs.job_cost`) and publishes its state when the
job completes (:func:`done`); a newer command stamped far enough in the past rolls the
node back (:mod:`~sigma_des.events.fast.warp`).
"""

from __future__ import annotations

from sigma_des.events.fast.clock import local_time
from sigma_des.events.fast.codes import (
    E_AUX,
    E_FRAME,
    E_INDEX,
    E_KIND,
    E_WHO,
    EF_GEN,
    EF_L,
    EF_TPUB,
    I_HMISS,
    K_COMMAND,
    K_REPUB,
    K_REREQ,
    K_STATE,
    K_TRIGGER,
    N_BUSY,
    N_CSTAMP,
    N_FRAME,
    N_RB,
    N_REQ,
    N_TARGET,
    Q_HLC,
    Q_LOCK,
    Q_M,
    Q_THETA,
    Q_W,
    Q_WARP,
)
from sigma_des.events.fast.job import start_job
from sigma_des.events.fast.layout import (
    CL_OF,
    CMD,
    CRASH,
    EV_FLOAT,
    EV_INT,
    HLC_C,
    HLC_L,
    INTS,
    IPARAMS,
    LAST_FLOAT,
    LAST_INT,
    NODE,
    OBS_HIST,
    POOL,
    SLOT_FRAME,
)
from sigma_des.events.fast.primitives import (
    alloc,
    give_payload,
    jit,
    payload,
    put_int,
    row_of,
)
from sigma_des.events.fast.transport import send_up
from sigma_des.events.fast.warp import rollback

__all__ = ["at_node", "done"]


@jit
def _local(S, i, t):  # type: ignore[no-untyped-def]
    return local_time(S, i, t)


@jit
def _request(S, i, frame, now):  # type: ignore[no-untyped-def]
    """MethodRun._on_trigger: ask node ``i`` for ``frame`` (starts it if idle)."""
    nd = S[NODE]
    if frame > nd[N_REQ, i]:
        nd[N_REQ, i] = frame
        if nd[N_BUSY, i] == 0:
            start_job(S, i, now)


@jit
def _publish_state(S, i, target, now):  # type: ignore[no-untyped-def]
    """Node ``i`` publishes its state of frame ``target`` (kept for re-requests)."""
    h = S[SLOT_FRAME].shape[0]
    sl = row_of(target, h)
    if S[SLOT_FRAME][sl] != target:
        S[INTS][I_HMISS] += 1
    ns = alloc(S)
    evf = S[EV_FLOAT]
    evi = S[EV_INT]
    w = S[IPARAMS][Q_W]
    evf[ns, EF_TPUB] = now
    evf[ns, EF_GEN] = now
    oh = S[OBS_HIST]
    pool = S[POOL]
    r = give_payload(S, ns)
    for j in range(w):
        pool[r, j] = oh[sl, i, j]
    if S[IPARAMS][Q_HLC]:  # HLC.send at the node's local time
        pt = _local(S, i, now)
        hl = S[HLC_L]
        old = hl[i]
        new = pt if pt > old else old
        S[HLC_C][i] = S[HLC_C][i] + 1 if new == old else 0
        hl[i] = new
        evf[ns, EF_L] = new
        put_int(S, ns, E_AUX, S[HLC_C][i])
    evi[ns, E_FRAME] = target
    if S[IPARAMS][Q_LOCK]:  # kept for re-requests (MethodRun.last_pub)
        li = S[LAST_INT]
        lf = S[LAST_FLOAT]
        li[i, 0] = target
        li[i, 1] = evi[ns, E_AUX]
        lf[i, 0] = now
        lf[i, 1] = evf[ns, EF_L]
        for j in range(w):
            lf[i, 2 + j] = pool[r, j]
    send_up(S, ns, S[CL_OF][i], K_STATE, i, target, now)  # through i's MQTT client


@jit
def done(S, s, now):  # type: ignore[no-untyped-def]
    """The job in event slot ``s`` completes at ``now`` (MethodRun._complete)."""
    nd = S[NODE]
    i = S[EV_INT][s, E_WHO]
    target = S[EV_INT][s, E_INDEX]
    nd[N_BUSY, i] = 0
    if now >= S[CRASH][i]:
        return
    if target > nd[N_FRAME, i]:
        nd[N_FRAME, i] = target
        _publish_state(S, i, target, now)
    if nd[N_REQ, i] > nd[N_FRAME, i] or nd[N_RB, i] != 0:
        start_job(S, i, now)


@jit
def _hlc_receive(S, i, now, ml, mc):  # type: ignore[no-untyped-def]
    """HLC.receive of stamp ``(ml, mc)`` at node ``i``'s local time."""
    pt = _local(S, i, now)
    hl = S[HLC_L]
    hc = S[HLC_C]
    old = hl[i]
    new = old
    if ml > new:
        new = ml
    if pt > new:
        new = pt
    if new == old and new == ml:
        hc[i] = max(hc[i], mc) + 1
    elif new == old:
        hc[i] += 1
    elif new == ml:
        hc[i] = mc + 1
    else:
        hc[i] = 0
    hl[i] = new


@jit
def _rerequest(S, s, i, now):  # type: ignore[no-untyped-def]
    """MethodRun._on_rerequest: republish the kept state, or ask for the frame."""
    evi = S[EV_INT]
    evf = S[EV_FLOAT]
    frame = evi[s, E_FRAME]
    li = S[LAST_INT]
    if S[NODE][N_FRAME, i] >= frame and li[i, 0] == frame:
        ns = alloc(S)
        lf = S[LAST_FLOAT]
        evf[ns, EF_TPUB] = now
        evf[ns, EF_GEN] = lf[i, 0]
        evf[ns, EF_L] = lf[i, 1]
        pool = S[POOL]
        r = give_payload(S, ns)
        for j in range(S[IPARAMS][Q_W]):
            pool[r, j] = lf[i, 2 + j]
        evi[ns, E_AUX] = li[i, 1]
        evi[ns, E_FRAME] = frame
        send_up(S, ns, S[CL_OF][i], K_REPUB, i, evi[s, E_INDEX], now)
    elif S[NODE][N_REQ, i] < frame:
        _request(S, i, frame, now)


@jit
def _command(S, s, i, now):  # type: ignore[no-untyped-def]
    """MethodRun._on_command: apply a newer command; far in the past, roll back."""
    nd = S[NODE]
    q = S[IPARAMS]
    stamp = S[EV_INT][s, E_AUX]
    if stamp < nd[N_CSTAMP, i]:
        return  # an older command overtaken by a newer one
    nd[N_CSTAMP, i] = stamp
    cmd = S[CMD]
    pool = S[POOL]
    r = payload(S, s)
    for j in range(q[Q_M]):
        cmd[i, j] = pool[r, j]
    if not q[Q_WARP] or stamp < 0:
        return
    current = nd[N_TARGET, i] if nd[N_BUSY, i] else nd[N_FRAME, i]
    if current - stamp <= q[Q_THETA]:
        return
    rollback(S, i, stamp, current, now)


@jit
def at_node(S, s, now):  # type: ignore[no-untyped-def]
    """A trigger, re-request or command (slot ``s``) reaches its (live) node."""
    evi = S[EV_INT]
    i = evi[s, E_WHO]
    kind = evi[s, E_KIND]
    if now >= S[CRASH][i]:
        return
    if kind == K_TRIGGER:
        if S[IPARAMS][Q_HLC]:
            _hlc_receive(S, i, now, S[EV_FLOAT][s, EF_L], evi[s, E_AUX])
        _request(S, i, evi[s, E_INDEX], now)
    elif kind == K_COMMAND:
        _command(S, s, i, now)
    elif kind == K_REREQ:
        _rerequest(S, s, i, now)
