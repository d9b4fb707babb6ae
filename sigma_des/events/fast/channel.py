"""Channels: the hops of one direction as few queue entries (docs/concepts/engines.md).

In the specification every hop's arrival is an event keyed ``(arrival, sequence)``.
Without hold-back on the links, a hop down (a delivery leaving the broker: its FIFO
makes departures one cumulative sum) or up (a publish leaving now, over a FIFO link)
mostly arrives no earlier than the hop of that direction queued just before it, and
its sequence number, taken as the specification's push takes it, is the newest. Such
arrivals are *sorted as they come*: a channel keeps them in a ring (``ch_t``, ``ch_k``:
arrival and ``sequence << SLOT_BITS | slot`` of the hop's own event slot), and only
its head is in the queue, as a *token* (an ``EV_CHAN`` slot keyed by the head's
arrival and sequence). When the loop takes the token, the head's event runs (the same
handler on the same slot: :func:`take`) and the token goes back under the next
element's key (:func:`requeue`). The token lives in a run of its own
(:func:`~sigma_des.events.fast.queue.own_run`), so it goes back in place even when
other events fall between two elements: the channel's events are never sorted or
merged by the pending buffer. The queue yields the specification's events in the
specification's order: results are bit-identical.

A hop whose arrival is earlier than the channel's last (a busier link, a longer
latency or serialization) or that finds the ring full is queued as a plain event, as
is every hop of a run with a CPU stage, QoS 1 over datagram or a stream with
hold-back (:func:`applies`). A lost hop takes no sequence number, as in the
specification.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import NDArray

from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import fanout
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.codes import (
    CH_FULL,
    CH_HEAD,
    CH_MOVE,
    CH_OOO,
    CH_RUN,
    CH_TOKEN,
    CH_USED,
    E_KIND,
    E_PAY,
    E_TYPE,
    E_WHO,
    EV_BROKER,
    EV_CHAN,
    I_EID,
    I_NEV,
    Q_CHAN,
    SLOT_BITS,
    SLOT_MASK,
)
from sigma_des.events.fast.layout import (
    CH_INT,
    CH_K,
    CH_T,
    EV_FLOAT,
    EV_INT,
    INTS,
    IPARAMS,
    WIRE_BYTES,
)
from sigma_des.events.fast.prefetch import prefetch
from sigma_des.events.fast.primitives import (
    alloc,
    count,
    fly,
    jit,
    key_of,
    push,
    push_key,
    release,
)
from sigma_des.events.fast.queue import back_in_place, own_run

__all__ = ["ENABLED", "applies", "arrive", "batching", "hop", "requeue", "take"]

#: Hops go through channels where they can (results are bit-identical either way;
#: False: one queue entry per hop, as in the specification). Read when a run's core is
#: built.
ENABLED = True


def applies(S: tuple[NDArray[Any], ...]) -> bool:
    """Whether the run's hops go through channels: :data:`ENABLED` and
    :func:`~sigma_des.events.fast.fanout.one_event_hops` (a hop is one event)."""
    return ENABLED and fanout.one_event_hops(S)


def batching(S: tuple[NDArray[Any], ...]) -> None:
    """Set the run's batching switches: broadcasts fan out in batches (``Q_FAN``,
    :func:`sigma_des.events.fast.fanout.applies`), hops go through channels (``Q_CHAN``)."""
    S[L.IPARAMS][CO.Q_FAN] = int(fanout.applies(S))
    S[L.IPARAMS][Q_CHAN] = int(applies(S))


@jit
def arrive(S, ch, t, slot):  # type: ignore[no-untyped-def]
    """Queue the arrival at ``t`` of the hop in ``slot`` through channel ``ch`` (0: down,
    1: up): its sequence number is the creation order, as :func:`push` takes it."""
    iv = S[INTS]
    e = iv[I_EID]
    iv[I_EID] = e + 1
    iv[I_NEV] += 1
    key = (e << SLOT_BITS) | slot
    ci = S[CH_INT][ch]
    ct = S[CH_T][ch]
    ck = S[CH_K][ch]
    r = ct.shape[0]
    u = ci[CH_USED]
    h = ci[CH_HEAD]
    if u == 0:  # the channel's first element: a token for it, in a run of its own
        tok = alloc(S)
        evi = S[EV_INT]
        evi[tok, E_TYPE] = EV_CHAN
        evi[tok, E_WHO] = ch
        evi[tok, E_KIND] = 0
        evi[tok, E_PAY] = 0
        ci[CH_TOKEN] = tok
        ct[h] = t
        ck[h] = key
        ci[CH_USED] = 1
        own_run(S, t, (e << SLOT_BITS) | tok)
        return
    last = h + u - 1
    if last >= r:
        last -= r
    if u == r:
        ci[CH_FULL] += 1
        push_key(S, t, key)
        return
    if t < ct[last]:
        ci[CH_OOO] += 1
        push_key(S, t, key)
        return
    i = last + 1 if last + 1 < r else 0
    ct[i] = t
    ck[i] = key
    ci[CH_USED] = u + 1


@jit
def take(S, tok):  # type: ignore[no-untyped-def]
    """The loop took token ``tok``: its channel's head element leaves the ring; its event
    slot (the handler runs it, the loop frees it)."""
    ch = S[EV_INT][tok, E_WHO]
    ci = S[CH_INT][ch]
    h = ci[CH_HEAD]
    s = S[CH_K][ch, h] & SLOT_MASK
    ci[CH_HEAD] = h + 1 if h + 1 < S[CH_T].shape[1] else 0
    ci[CH_USED] -= 1
    ci[CH_RUN] += 1
    return s


@jit
def _warm(S, ch, h, u):  # type: ignore[no-untyped-def]
    """Start loading what channel ``ch``'s head (ring row ``h`` of ``u`` used) will read
    when taken, and its next element's slot rows: the head's slot rows were asked for one
    re-queue ago, so its payload row and, for a state reaching the server, the aligner's
    ring rows it is stored in can be found now (as the loop's ``_ahead`` does for a run)."""
    ck = S[CH_K][ch]
    s = ck[h] & SLOT_MASK
    evi = S[EV_INT]
    prefetch(evi, s)
    prefetch(S[EV_FLOAT], s)
    r = evi[s, E_PAY] - 1
    if r >= 0:
        prefetch(S[L.POOL], r)
    ip = S[IPARAMS]
    if ch == 0 and evi[s, E_WHO] == ip[CO.Q_N] and ip[CO.Q_RING]:
        subj = evi[s, CO.E_SUBJ]
        slot = evi[s, CO.E_FRAME] % S[L.RING_FRAME].shape[1]
        prefetch(S[L.RING_FRAME][subj], slot)
        prefetch(S[L.RING_GEN][subj], slot)
        prefetch(S[L.RING_OBS][subj], slot)
    if u > 1:
        n = h + 1 if h + 1 < ck.shape[0] else 0
        prefetch(evi, ck[n] & SLOT_MASK)
        prefetch(S[EV_FLOAT], ck[n] & SLOT_MASK)


@jit
def requeue(S, tok, c, p):  # type: ignore[no-untyped-def]
    """After its head's event ran: token ``tok``, taken at arena row ``p`` of run ``c``,
    goes back under its channel's next element's key; False if the channel is empty
    (the token's slot is freed).

    In place (row ``p``, the run's head again) when the run has no next entry (a run of
    its own) or that key precedes it; else into a run of its own (:func:`own_run`).
    """
    ch = S[EV_INT][tok, E_WHO]
    ci = S[CH_INT][ch]
    if ci[CH_USED] == 0:
        ci[CH_TOKEN] = -1
        return False
    h = ci[CH_HEAD]
    _warm(S, ch, h, ci[CH_USED])
    t = S[CH_T][ch, h]
    k = (S[CH_K][ch, h] & ~SLOT_MASK) | tok
    if not back_in_place(S, c, p, t, k):
        ci[CH_MOVE] += 1
        own_run(S, t, k)
    return True


@jit
def hop(S, slot, t):  # type: ignore[no-untyped-def]
    """Network._hop for the message in ``slot`` (addressed): queue it at its arrival.

    FIFO serialization on the receiver's (down) or sender's (up) link, latency and
    loss (time-dependent: Gilbert–Elliott state, degrade windows and drop faults,
    :mod:`~sigma_des.events.fast.loss`); a lost message frees its slot. The arrival
    goes through the direction's channel (``Q_CHAN``), else into the queue.

    Returns:
        (arrival time, lost?) of this transmission.
    """
    evi = S[EV_INT]
    client = evi[slot, E_WHO]
    kind, subj, index = key_of(S, slot)
    up = 1 if evi[slot, E_TYPE] == EV_BROKER else 0
    done = count(S, client, up, S[WIRE_BYTES][kind], t)
    arr, lost = fly(S, client, up, kind, subj, index, evi[slot, CO.E_ATT], False, done, t)
    if lost:
        release(S, slot)
    elif S[IPARAMS][Q_CHAN]:
        arrive(S, up, arr, slot)
    else:
        push(S, arr, slot)
    return arr, lost
