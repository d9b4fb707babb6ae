"""What a client's application gets, in the compiled message core (docs/concepts/deployment.md).

``Network._client_receive`` and ``_hand_over``, with the same operations in the
same order: a copy that reaches its client (after the PUBACK) is a burst of the
client's process when its demand is not zero — its latency ends at the burst's start
(with ``lock_switch``, for a copy reaching a busy process, when its batch is read),
the application gets it at the burst's end, an ``EV_APP`` event (:func:`receive`; with a
network thread, that thread's burst, at whose end the latency ends and the application
gets it, an ``EV_LOOP`` event; the loop thread's burst is charged then:
:func:`loop_receive`) — and is then handed over
(:func:`hand_over`): to the server's aligner, to the node it reached, or, with
per-host clients, from the host's client to its nodes (a trigger to each in node
order, a command or re-request to the node it is about), each hand-over counted
as a delivery (``Collector.delivered``) to that node.
"""

from __future__ import annotations

import math

from sigma_des.events.fast.codes import (
    CP_HOSTS,
    E_ATT,
    E_KIND,
    E_SUBJ,
    E_TACT,
    E_TYPE,
    E_WHO,
    EF_TRECV,
    EV_APP,
    EV_LOOP,
    K_TRIGGER,
    Q_N,
    TA_ARRIVE,
    TA_READ,
)
from sigma_des.events.fast.cpu import burst, net_span, span, threaded
from sigma_des.events.fast.layout import (
    CPU_DEM,
    CPU_FREE,
    CPU_INB,
    CPU_IP,
    CPU_PROC,
    CPU_SWITCH,
    EV_FLOAT,
    EV_INT,
    IPARAMS,
    MEM,
    MEM_PTR,
)
from sigma_des.events.fast.node import at_node
from sigma_des.events.fast.primitives import alloc, jit, push
from sigma_des.events.fast.server import at_server, delivered
from sigma_des.events.fast.transport import copy_slot

__all__ = ["hand_over", "loop_receive", "receive"]


@jit
def _to_node(S, s, j, now, t_recv):  # type: ignore[no-untyped-def]
    """Hand the copy in slot ``s`` to node ``j`` (its receiver and draw subject)."""
    evi = S[EV_INT]
    evi[s, E_WHO] = j
    evi[s, E_SUBJ] = j
    delivered(S, s, t_recv)
    at_node(S, s, now)


@jit
def hand_over(S, s, now, t_recv):  # type: ignore[no-untyped-def]
    """Network._hand_over: the receiving client's application gets the copy in ``s`` at
    ``now``; it reached the client at ``t_recv`` (where its latency ends)."""
    evi = S[EV_INT]
    c = evi[s, E_WHO]
    if c == S[IPARAMS][Q_N]:
        delivered(S, s, t_recv)
        at_server(S, s, now)
    elif not S[CPU_IP][CP_HOSTS]:
        delivered(S, s, t_recv)
        at_node(S, s, now)
    elif evi[s, E_KIND] == K_TRIGGER:  # the broadcast: to every node of the host
        ptr = S[MEM_PTR]
        mem = S[MEM]
        for m in range(ptr[c], ptr[c + 1]):
            _to_node(S, s, mem[m], now, t_recv)
    else:  # a message about one node (command, re-request): to that node
        _to_node(S, s, evi[s, E_SUBJ], now, t_recv)


@jit
def receive(S, s, now):  # type: ignore[no-untyped-def]
    """The copy in ``s`` reached its client at ``now`` (its PUBACK already sent): a burst
    of the client's process, then the hand-over (an ``EV_APP`` event), or the
    hand-over at once for a zero demand."""
    c = S[EV_INT][s, E_WHO]
    p = S[CPU_PROC][c]
    if p < 0:
        hand_over(S, s, now, now)
        return
    evi = S[EV_INT]
    read = math.nan
    if evi[s, E_TACT] == TA_READ:  # held by the stream, read at its own arrival
        read = S[EV_FLOAT][s, EF_TRECV]
        evi[s, E_TACT] = TA_ARRIVE
    ns = alloc(S)  # the event's slot is freed after it: a copy waits for the burst
    copy_slot(S, s, ns)
    evi[ns, E_TYPE] = EV_APP
    evi[ns, E_ATT] = 0  # the application ignores the attempt (no draws to fill for it)
    if threaded(S, p):  # Network._client_receive: the network thread reads and stamps it
        evi[ns, E_TYPE] = EV_LOOP  # stamped at that burst's end: the event's time
        if read != read:
            read = net_span(S, p, now, True)[1]
        push(S, read if read > now else now, ns)
        return
    busy = S[CPU_FREE][p] > now
    start, end = span(S, p, S[CPU_DEM][c], now)
    sw = S[CPU_SWITCH][p]
    if busy and sw > 0.0:  # Network._read_batch: read with the batch, when the thread frees
        bt = S[CPU_INB][p]
        if bt <= now:
            bt = start if start < now + sw else now + sw
            S[CPU_INB][p] = bt
        start = bt
    S[EV_FLOAT][ns, EF_TRECV] = start  # the process gets to it: where the latency ends
    push(S, end, ns)


@jit
def loop_receive(S, s, now):  # type: ignore[no-untyped-def]
    """Network._loop_receive: the copy in ``s``, read and stamped by its process's
    network thread at ``now`` (that burst's end): a loop-thread burst of the client's
    demand, and the hand-over at once."""
    c = S[EV_INT][s, E_WHO]
    burst(S, S[CPU_PROC][c], S[CPU_DEM][c], now)
    hand_over(S, s, now, now)
