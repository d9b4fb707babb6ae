"""Publishes waiting for their process's thread, in the compiled message core
(docs/concepts/deployment.md, ``deployment.lock_switch``).

``Network._burst_done`` and ``_leave`` with the same operations in the same order: a
PUBLISH whose publish burst ends while its process's thread is busy (or while earlier
ones of that process wait) joins the process's outbox, a ring of slots; the first one
schedules a check (an ``EV_LEAVE`` event) when the thread is next free or
``lock_switch`` after its burst's end, whichever is first. At the check, if the thread
is idle or the switch is due, the whole outbox leaves in order; else the check is
made again then. More than :data:`~sigma_des.events.fast.codes.OB_CAP` waiting
publishes of one process is an error (``ERR_OUTBOX``): the run falls back to the
per-message engine.
"""

from __future__ import annotations

from typing import Any

from sigma_des.events.fast.codes import (
    CP_SWITCH,
    E_ATT,
    E_TYPE,
    E_WHO,
    EV_LEAVE,
    I_ERR,
    OB_CAP,
    T_QOS1D,
)
from sigma_des.events.fast.layout import (
    CPU_FREE,
    CPU_IP,
    CPU_OB,
    CPU_OBQ,
    CPU_OBT,
    CPU_PROC,
    CPU_SWITCH,
    ERR_OUTBOX,
    EV_INT,
    INTS,
    TR_PARAMS,
)
from sigma_des.events.fast.primitives import alloc, jit, push
from sigma_des.events.fast.transport import net_send

__all__ = ["burst_done", "leave", "outbox_room"]


def outbox_room(S: tuple[Any, ...]) -> int:
    """Spare slots (and payload rows) the loop keeps free for outbox checks (as
    ``loop._limits``): a check sends up to ``OB_CAP`` messages, each with a copy or two."""
    if not int(S[CPU_IP][CP_SWITCH]):
        return 0
    return (2 + int(S[TR_PARAMS][T_QOS1D])) * OB_CAP


@jit
def _check(S, client, t):  # type: ignore[no-untyped-def]
    """Schedule the outbox check of ``client``'s process at ``t``."""
    ck = alloc(S)
    evi = S[EV_INT]
    evi[ck, E_TYPE] = EV_LEAVE
    evi[ck, E_WHO] = client
    evi[ck, E_ATT] = 0  # draws nothing
    push(S, t, ck)


@jit
def burst_done(S, ns, now):  # type: ignore[no-untyped-def]
    """Network._burst_done: the PUBLISH in slot ``ns`` (its own copy) has had its
    publish burst; it leaves now or waits in its process's outbox."""
    client = S[EV_INT][ns, E_WHO]
    p = S[CPU_PROC][client]
    q = S[CPU_OBQ]
    n = q[p, 1]
    free = S[CPU_FREE][p]
    if n == 0 and not free > now:
        net_send(S, ns, now)
        return
    if n >= OB_CAP:
        S[INTS][I_ERR] = ERR_OUTBOX
        return
    S[CPU_OB][p, (q[p, 0] + n) % OB_CAP] = ns
    q[p, 1] = n + 1
    if n == 0:  # the first: a check when the thread is free or the switch is due
        due = now + S[CPU_SWITCH][p]
        S[CPU_OBT][p] = due
        _check(S, client, free if free < due else due)


@jit
def leave(S, s, now):  # type: ignore[no-untyped-def]
    """Network._leave: the outbox check in slot ``s`` (its client in ``E_WHO``)."""
    client = S[EV_INT][s, E_WHO]
    p = S[CPU_PROC][client]
    free = S[CPU_FREE][p]
    due = S[CPU_OBT][p]
    if free > now and due > now:
        _check(S, client, free if free < due else due)
        return
    q = S[CPU_OBQ]
    h = q[p, 0]
    n = q[p, 1]
    q[p, 0] = (h + n) % OB_CAP
    q[p, 1] = 0
    ob = S[CPU_OB]
    for j in range(n):
        net_send(S, ob[p, (h + j) % OB_CAP], now)
