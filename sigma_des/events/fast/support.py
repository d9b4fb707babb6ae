"""What the compiled message core reproduces, and the error when it cannot.

Features whose per-message behaviour the core does not reproduce are listed by
:func:`unsupported`; a run that needs them uses the per-message engine for the
whole run and says why (docs/MODEL.md, "Engines").
"""

from __future__ import annotations

from sigma_des.events.spec import RunSpec

__all__ = ["CohortFallback", "unsupported"]


class CohortFallback(RuntimeError):
    """The cohort core met something it cannot reproduce exactly (run per message)."""


def unsupported(sc: RunSpec, method: str) -> str | None:
    """Why ``method`` on the run ``sc`` cannot run on the cohort core (None: it can).

    These features fall back to the per-message engine for the whole run: drop and
    degrade faults, NTP-corrected clocks, Gilbert–Elliott loss; the DDS middleware
    and the ``rpc`` method (issue 16: per-message models only). MQTT QoS 1 over
    datagrams (PUBACK hops, resends, redelivery) and the stream transport on a link
    with loss or random latency (in-order hold-back, RTO retries, give-ups) run on
    the core (:mod:`sigma_des.events.fast.transport`, :mod:`~sigma_des.events.fast.stream`).
    """
    why: list[str] = []
    kinds = sorted({f.kind for f in sc.faults} - {"crash", "slow"})
    if kinds:
        why.append(f"faults of kind {', '.join(kinds)}")
    if sc.clocks.ntp_period > 0:
        why.append("NTP-corrected clocks")
    net = sc.net.net
    for name, link in (("host_link", net.host_link), ("server_link", net.server_link)):
        if link.loss.model != "bernoulli":
            why.append(f"{name}: Gilbert-Elliott loss")
    if net.middleware == "dds":
        why.append("DDS middleware (per-reader sends, participant threads, heartbeats, discovery)")
    if method == "rpc":
        why.append("rpc method (per-vehicle synchronous calls, game-thread render)")
    return "; ".join(why) if why else None
