"""The transports' resend rules and in-order release, on hand-computed cases.

The simulated stream (``Links._stream_try``/``_stream_arrive``) and the live shim both
apply these; the shim's side is checked here against the DES's own give-up ordering.
"""

from __future__ import annotations

import math

from sigma_des import load
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.live.shim import UP, Impairment
from sigma_des.net.message import Msg
from sigma_des.net.network import Network
from sigma_des.net.resend import InOrderRelease, Tries, resend_wait, stream_backoff, walk_tries
from sigma_des.net.spec import NetSpec


def _fates(*lost: bool):  # type: ignore[no-untyped-def]
    """``lost(offset, attempt)`` from a fixed list of fates, recording the offsets asked."""
    asked: list[tuple[float, int]] = []

    def lost_try(offset: float, attempt: int) -> bool:
        asked.append((offset, attempt))
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
    assert walk_tries(stream, lost) == Tries(0.75, 2, False, 0.75)  # 0.25 + 0.5
    assert asked == [(0.0, 0), (0.25, 1), (0.75, 2)]
    lost, asked = _fates(True, True, True, True)
    assert walk_tries(stream, lost) == Tries(math.inf, 4, True, 1.75)  # last try at 1.75
    assert [a for _o, a in asked] == [0, 1, 2, 3]
    qos0 = NetSpec(transport="datagram", qos=0)
    assert walk_tries(qos0, _fates(True)[0]) == Tries(math.inf, 1, False, 0.0)
    qos1 = NetSpec(transport="datagram", qos=1, qos1_timeout=0.1, max_retries=1)
    assert walk_tries(qos1, _fates(True, False)[0]) == Tries(0.1, 1, False, 0.1)
    assert walk_tries(qos1, _fates(False)[0]) == Tries(0.0, 0, False, 0.0)


def test_in_order_release_waits_for_the_message_sent_before() -> None:
    order = InOrderRelease()
    assert [order.release(t) for t in (0.3, 0.1, 0.5, 0.4)] == [0.3, 0.3, 0.5, 0.5]
    order.give_up(0.9)  # a given-up message holds the later ones until its last try
    assert order.release(0.6) == 0.9
    order.give_up(0.2)  # an earlier give-up changes nothing
    assert order.release(1.0) == 1.0


def test_the_des_stream_holds_later_segments_behind_a_given_up_one() -> None:
    """``Links``: a segment lost on every try releases the segments behind it when it
    is given up (its last try); the shim keeps the same order (its give-up at
    ``t + rto·(2^(max_retries) - 1)``)."""

    sets = ["nodes=2", "hosts=1", "net.host_link.loss.p=0.5", "net.transport='stream'",
            "net.rto=0.1", "net.max_retries=1", "net.host_link.latency.value=0.002"]
    sc = load(None, sets)
    imp = Impairment(sc.net.host_link, sc.net, RandomStreams(sc.seed), 0)
    lost = RandomStreams(sc.seed).stream("lossu.host.up")
    fates = [[bool(lost.uniform(2, 0, k, a)[()] < 0.5) for a in range(2)] for k in range(40)]
    gone = next(k for k, f in enumerate(fates) if all(f))  # lost on both tries
    after = next(k for k in range(gone + 1, 40) if not fates[k][0])  # through at once
    assert imp.delay(0.0, UP, 2, 0, gone) == math.inf
    # sent 1 ms later, it arrives at 0.003 s but waits for the give-up at 0.1 s
    assert imp.delay(0.001, UP, 2, 0, after) == 0.1 - 0.001
    # the DES's stream: the same two messages on node 0's uplink
    k = Kernel()
    got: list[tuple[float, int]] = []
    net = Network(k, sc.net_setup(), RandomStreams(sc.seed), lambda m: None)
    for t, idx in ((0.0, gone), (0.001, after)):
        m = Msg(0, 2, 0, idx, None, 100, (), 0, t, t)
        k.at(t, net.transmit, m, True, 100, lambda m: got.append((k.now, m.index)))
    k.run(until=1.0)
    assert got == [(0.1, after)]
    assert net.gave_up == 1
