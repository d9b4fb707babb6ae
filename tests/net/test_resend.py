"""The transports' resend rules and in-order release, on hand-computed cases.

The simulated stream (``Links._stream_try``/``_stream_arrive``) and the live shim both
apply these (tests/live/test_shim.py checks the shim against the DES's stream).
"""

from __future__ import annotations

import math

from sigma_des.net.resend import InOrderRelease, Tries, resend_wait, stream_backoff, walk_tries
from sigma_des.net.spec import NetSpec


def _fates(*lost: bool):  # type: ignore[no-untyped-def]
    """``lost(t_try, attempt)`` from a fixed list of fates, recording the tries asked."""
    asked: list[tuple[float, int]] = []

    def lost_try(t_try: float, attempt: int) -> bool:
        asked.append((t_try, attempt))
        return lost[attempt]

    return lost_try, asked


def test_the_stream_doubles_its_wait_and_qos1_waits_its_timeout() -> None:
    assert [stream_backoff(0.2, a) for a in range(4)] == [0.2, 0.4, 0.8, 1.6]
    stream = NetSpec(transport="stream", rto=0.25)
    assert [resend_wait(stream, a) for a in range(3)] == [0.25, 0.5, 1.0]
    qos1 = NetSpec(transport="datagram", qos=1, qos1_timeout=0.05)
    assert [resend_wait(qos1, a) for a in range(3)] == [0.05, 0.05, 0.05]
    assert resend_wait(NetSpec(transport="datagram", qos=0), 0) == math.inf


def test_walking_the_tries_of_one_message() -> None:
    stream = NetSpec(transport="stream", rto=0.25, max_retries=3)
    lost, asked = _fates(True, True, False, False)
    assert walk_tries(stream, 2.0, lost) == Tries(2.75, 2, False, 2.75)  # 2 + 0.25 + 0.5
    assert asked == [(2.0, 0), (2.25, 1), (2.75, 2)]
    lost, asked = _fates(True, True, True, True)
    assert walk_tries(stream, 2.0, lost) == Tries(math.inf, 4, True, 3.75)  # last try
    assert [a for _t, a in asked] == [0, 1, 2, 3]
    qos0 = NetSpec(transport="datagram", qos=0)
    assert walk_tries(qos0, 2.0, _fates(True)[0]) == Tries(math.inf, 1, False, 2.0)
    qos1 = NetSpec(transport="datagram", qos=1, qos1_timeout=0.125, max_retries=1)
    assert walk_tries(qos1, 2.0, _fates(True, False)[0]) == Tries(2.125, 1, False, 2.125)
    assert walk_tries(qos1, 2.0, _fates(False)[0]) == Tries(2.0, 0, False, 2.0)


def test_in_order_release_waits_for_the_message_sent_before() -> None:
    order = InOrderRelease()
    assert [order.release(t) for t in (0.3, 0.1, 0.5, 0.4)] == [0.3, 0.3, 0.5, 0.5]
    order.give_up(0.9)  # a given-up message holds the later ones until its last try
    assert order.release(0.6) == 0.9
    order.give_up(0.2)  # an earlier give-up changes nothing
    assert order.release(1.0) == 1.0
