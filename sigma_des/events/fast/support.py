"""What the compiled message core reproduces, and the error when it cannot.

Features whose per-message behaviour the core does not reproduce are listed by
:func:`unsupported`; a run that needs them uses the per-message engine for the
whole run and says why (docs/concepts/engines.md). The link and clock tables the
core reads for Gilbert–Elliott loss and NTP clocks cover the run and
:data:`TABLE_MARGIN` seconds more; :func:`ge_slots` and :func:`ntp_syncs` size
them.
"""

from __future__ import annotations

import math

from sigma_des.events.fast.layout import EV_INT_MAX
from sigma_des.events.fast.memo import IdentityMemo
from sigma_des.events.spec import RunSpec

__all__ = ["MAX_TABLE_BYTES", "TABLE_MARGIN", "CohortFallback", "checked_int", "ge_slots",
           "check_support", "ntp_syncs", "unsupported"]

#: Seconds past the run's end covered by the Gilbert–Elliott and NTP tables (a send
#: later than that, behind a broker backlog this long, stops the compiled run and
#: the whole run is made per message).
TABLE_MARGIN = 1.0
#: Largest Gilbert–Elliott or NTP table the core builds (bytes); beyond, fall back.
MAX_TABLE_BYTES = 1 << 26


class CohortFallback(RuntimeError):
    """The cohort core met something it cannot reproduce exactly (run per message)."""


def checked_int(value: int, what: str) -> int:
    """``value``, which the driver stores in an event slot's int32 column.

    Raises:
        CohortFallback: it lies beyond the column (``what`` names it): the whole run is
            made per message, where Python integers have no bound.
    """
    if not -EV_INT_MAX - 1 <= value <= EV_INT_MAX:
        raise CohortFallback(
            f"{what} {value} beyond the event table's int32 columns (largest {EV_INT_MAX})"
        )
    return value


def ge_slots(sc: RunSpec) -> int:
    """Chain slots of the core's Gilbert–Elliott table (1: no link uses the model)."""
    horizon = sc.duration + TABLE_MARGIN
    net = sc.net.net
    slots = [
        math.floor(horizon / link.loss.slot) + 1
        for link in (net.host_link, net.server_link)
        if link.loss.model == "gilbert_elliott"
    ]
    return max(slots, default=1)


def ntp_syncs(sc: RunSpec) -> int:
    """Columns of the core's NTP residual table: sync indices ``0 ... j_max`` (1: no NTP)."""
    period = sc.clocks.ntp_period
    if period <= 0.0:
        return 1
    return math.floor((sc.duration + TABLE_MARGIN) / period) + 2


def unsupported(sc: RunSpec, method: str) -> str | None:
    """Why ``method`` on the run ``sc`` cannot run on the cohort core (None: it can):
    :func:`check_support`'s answer, kept per run spec's parts (they are what it reads;
    an env's episodes share them, :mod:`~sigma_des.events.fast.memo`)."""
    return _SUPPORT.get((sc.net, sc.faults, sc.clocks), (sc.nodes, sc.hosts, sc.duration, method),
                        lambda: check_support(sc, method))


_SUPPORT: IdentityMemo[str | None] = IdentityMemo()


def check_support(sc: RunSpec, method: str) -> str | None:
    """Why ``method`` on the run ``sc`` cannot run on the cohort core (None: it can).

    These features fall back to the per-message engine for the whole run: the DDS
    middleware and the ``rpc`` method (per-message models only); bundled
    states (``deployment.bundle``: a variable number of records in one PUBLISH); a
    Gilbert–Elliott or NTP table larger than :data:`MAX_TABLE_BYTES` (a very short
    slot or NTP period over a long run). The core reproduces Gilbert–Elliott loss,
    degrade and drop faults and NTP-corrected clocks, MQTT QoS 1 over datagrams
    (PUBACK hops, resends, redelivery: :mod:`~sigma_des.events.fast.transport`) and
    the stream transport on a link with loss or random latency (in-order hold-back,
    RTO retries, give-ups: :mod:`~sigma_des.events.fast.stream`), the CPU stage
    (:mod:`~sigma_des.events.fast.cpu`, processes' network threads included) and per-host clients
    (:mod:`~sigma_des.events.fast.clients`).
    """
    why: list[str] = []
    net = sc.net.net
    kinds = sorted({f.kind for f in sc.faults} - {"crash", "slow", "degrade", "drop"})
    if kinds:
        why.append(f"faults of kind {', '.join(kinds)}")
    if 8 * sc.nodes * ntp_syncs(sc) > MAX_TABLE_BYTES:
        why.append("NTP-corrected clocks: residual table too large (NTP period too short)")
    if 2 * (sc.hosts + 1) * ge_slots(sc) > MAX_TABLE_BYTES:
        why.append("Gilbert-Elliott loss: chain table too large (slot too short)")
    if net.middleware == "dds":
        why.append("DDS middleware (per-reader sends, participant threads, heartbeats, discovery)")
    if method == "rpc":
        why.append("rpc method (per-vehicle synchronous calls, game-thread render)")
    dep = sc.net.deployment
    if dep.bundle:
        why.append("deployment.bundle (a host's states of one loop turn as one PUBLISH)")
    return "; ".join(why) if why else None
