"""The compiled core's events by class: which ran from batches, and why the others did not.

The loop counts every event it runs by whether it ran one by one or from a batch (a
fan-out batch, :mod:`~sigma_des.events.fast.fanout`; a channel,
:mod:`~sigma_des.events.fast.channel`), its type and its message kind (``S.tally``); the
broker counts the deliveries of broadcasts it fanned out one by one although batching was
on (``I_BNOFIT``: a payload, or no room in the element ring), the fan-out those of
out-of-order broadcasts (``I_BSING``), each channel the hops it queued as plain events.
:func:`breakdown` turns these counters into classes whose counts add up to the events
run: broadcast deliveries, point-to-point deliveries (states to the server, commands and
re-requests to nodes), the broker's arrivals, the nodes' job ends, the transport's and
CPU stage's events. Deterministic: the same run gives the same counts (benchmarks print
them; nothing reads them to decide anything).
"""

from __future__ import annotations

from typing import Any

from numpy.typing import NDArray

from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L

__all__ = ["CLASSES", "breakdown"]

#: The classes of :func:`breakdown`, in report order, with what each holds.
CLASSES: dict[str, str] = {
    "bcast_deliv": "broadcast (trigger) deliveries",
    "state_deliv": "states (and republished states) delivered to the server",
    "command_deliv": "commands delivered to nodes",
    "rereq_deliv": "re-requests delivered to nodes",
    "broker_arrival": "publishes reaching the broker",
    "job_end": "nodes' compute jobs ending",
    "transport": "QoS 1 resend timers, stream retries and arrivals",
    "cpu_stage": "CPU-stage events (publish bursts, hand-overs, outboxes, network threads)",
}


def breakdown(S: tuple[NDArray[Any], ...]) -> dict[str, int]:
    """Events the core ran so far, by class (:data:`CLASSES`), and why some ran one by one.

    Per class ``c``: ``c`` the events run, ``c_batched`` those run from a fan-out batch or
    a channel. Then ``total`` and ``batched`` (their sums), the broker's reasons for
    queueing broadcast deliveries one by one with batching on (``bcast_out_of_order``,
    ``bcast_no_room``: a payload or no room in the element ring; counted when queued),
    the channels' (``down_``/``up_`` + ``out_of_order``, ``full``: hops queued as plain
    events), ``fanout_requeued`` (batches that went back through the pending buffer),
    ``chan_moved`` (tokens moved into a run of their own after another event fell
    between), and the switches ``fanout_on``, ``chan_on``.
    """
    t = S[L.TALLY]
    iv = S[L.INTS]
    out: dict[str, int] = {}
    for via, suffix in ((t.sum(axis=0), ""), (t[1], "_batched")):
        deliv = via[CO.EV_CLIENT]
        cls = {
            "bcast_deliv": deliv[CO.K_TRIGGER],
            "state_deliv": deliv[CO.K_STATE] + deliv[CO.K_REPUB],
            "command_deliv": deliv[CO.K_COMMAND],
            "rereq_deliv": deliv[CO.K_REREQ],
            "broker_arrival": via[CO.EV_BROKER].sum(),
            "job_end": via[CO.EV_DONE].sum(),
            "transport": via[CO.EV_RESEND].sum(),
            "cpu_stage": sum(via[e].sum() for e in (CO.EV_SEND, CO.EV_APP, CO.EV_LEAVE,
                                                    CO.EV_LOOP, CO.EV_NSEND)),
        }
        out.update({k + suffix: int(v) for k, v in cls.items()})
    out["total"] = int(t.sum())
    out["batched"] = int(t[1].sum())
    out["bcast_out_of_order"] = int(iv[CO.I_BSING])
    out["bcast_no_room"] = int(iv[CO.I_BNOFIT])
    ci = S[L.CH_INT]
    for ch, name in ((0, "down"), (1, "up")):
        out[f"{name}_out_of_order"] = int(ci[ch, CO.CH_OOO])
        out[f"{name}_full"] = int(ci[ch, CO.CH_FULL])
    out["fanout_requeued"] = int(iv[CO.I_BREIN])
    out["chan_moved"] = int(ci[:, CO.CH_MOVE].sum())
    out["fanout_on"] = int(S[L.IPARAMS][CO.Q_FAN])
    out["chan_on"] = int(S[L.IPARAMS][CO.Q_CHAN])
    return out
