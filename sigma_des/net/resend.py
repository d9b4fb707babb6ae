"""The transports' resend rules and in-order release (docs/MODEL.md, "Network"), defined once.

* ``stream`` (TCP-like): lost try ``a`` is resent :func:`stream_backoff` ``= rto · 2^a``
  later (the retransmission timeout doubles on each try), and each connection hands
  its messages on in the order they were sent; a given-up message takes its place in
  that order at the time of its last try.
* ``datagram`` with QoS 1: the sender resends when no PUBACK came within
  ``qos1_timeout`` (no doubling); with QoS 0 a lost message is gone.
* After ``max_retries`` resends are lost too, the message is given up.

The simulated network applies them as events (:class:`~sigma_des.net.links.Links`, and
the compiled core's :mod:`~sigma_des.events.fast.stream`, which compiles
:func:`stream_backoff` as it is). The live shim (:mod:`sigma_des.live.shim`) knows each
try's fate when it sends a message, so it walks the tries at once (:func:`walk_tries`)
and releases a stream's messages through :class:`InOrderRelease`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

from sigma_des.net.spec import NetSpec

__all__ = ["InOrderRelease", "Tries", "resend_wait", "stream_backoff", "walk_tries"]


def stream_backoff(rto: float, attempt: int) -> float:
    """Wait (s) before a stream resends lost try ``attempt`` (0 = the first try):
    ``rto · 2^attempt``. Plain arithmetic: the compiled core compiles this function."""
    return rto * (2**attempt)


def resend_wait(net: NetSpec, attempt: int) -> float:
    """Wait (s) after lost try ``attempt`` before the next try; ``inf``: never resent.

    Args:
        net: the network spec (transport, QoS, ``rto``, ``qos1_timeout``).
        attempt: the lost try (0 = the first).
    """
    if net.transport == "stream":
        return stream_backoff(net.rto, attempt)
    return net.qos1_timeout if net.qos == 1 else math.inf


class Tries(NamedTuple):
    """The tries of one message, as :func:`walk_tries` found them.

    Attributes:
        sent: when the try that gets through is sent (s); ``inf``: none does (the
            message is gone).
        lost: tries lost.
        gave_up: all ``max_retries + 1`` tries were lost (a QoS 0 datagram is gone
            after its one try without giving up).
        last: when the last try is sent (s).
    """

    sent: float
    lost: int
    gave_up: bool
    last: float

    @property
    def resent(self) -> int:
        """Lost tries that were sent again (the network's ``retransmissions``)."""
        return self.lost - 1 if math.isinf(self.sent) else self.lost


def walk_tries(net: NetSpec, t: float, lost: Callable[[float, int], bool]) -> Tries:
    """Apply the resend rule to one message whose tries' fates are known at once.

    Each try is sent at the previous try's time plus its wait, the very sum the
    simulated transport's clock makes (so the times are the DES's to the bit).

    Args:
        net: the network spec.
        t: when the first try is sent (s).
        lost: ``lost(t_try, attempt)``: is try ``attempt``, sent at ``t_try``, lost?
    """
    for attempt in range(net.max_retries + 1):
        if not lost(t, attempt):
            return Tries(t, attempt, False, t)
        wait = resend_wait(net, attempt)
        if math.isinf(wait):
            return Tries(math.inf, attempt + 1, False, t)
        if attempt == net.max_retries:
            break
        t = t + wait
    return Tries(math.inf, net.max_retries + 1, True, t)


class InOrderRelease:
    """One stream connection direction's in-order release, for a sender that knows
    each message's arrival when it sends it (messages in the order sent).

    A message is handed on at its arrival or when the one sent before it was, whichever
    is later; a given-up message holds those behind it until its last try, as the
    simulated stream's pending list does (``Links._stream_arrive``).
    """

    def __init__(self) -> None:
        self.last = 0.0

    def release(self, arrival: float) -> float:
        """When a message arriving at ``arrival`` is handed on."""
        self.last = max(arrival, self.last)
        return self.last

    def give_up(self, t: float) -> None:
        """A message was given up at ``t`` (its last try): later ones wait for it."""
        self.last = max(t, self.last)
