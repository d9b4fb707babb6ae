"""Client impairment shim: delays and loss decisions are the link spec's, draw for draw."""

from __future__ import annotations

import math
from typing import Any

import pytest

from sigma_des import load
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.live.shim import DOWN, UP, Impairment
from sigma_des.net.latency import Dist
from sigma_des.net.loss import LossSpec
from sigma_des.net.message import Msg
from sigma_des.net.network import Network
from sigma_des.net.spec import LinkSpec, NetSpec


def _des_loss(streams: RandomStreams, p: float, tag: str = "host.up") -> Any:
    """The DES's Bernoulli loss decision of a packet (``Links.hop``'s draw)."""
    st = streams.stream(f"lossu.{tag}")
    return lambda k, s, i, a: bool(st.uniform(k, s, i, a)[()] < p)


def test_disabled_or_zero_link_adds_nothing() -> None:
    st = RandomStreams(1)
    link = LinkSpec(latency=Dist(dist="constant", value=0.004), loss=LossSpec(p=0.5))
    assert Impairment(link, NetSpec(), st, 0, enabled=False).delay(0.0, UP, 2, 0, 0) == 0.0
    zero = LinkSpec(latency=Dist(dist="constant", value=0.0))
    assert Impairment(zero, NetSpec(), st, 0).delay(0.0, UP, 2, 0, 0) == 0.0


def test_constant_latency_and_stream_order() -> None:
    link = LinkSpec(latency=Dist(dist="uniform", low=0.001, high=0.009))
    imp = Impairment(link, NetSpec(transport="stream"), RandomStreams(3), 1)
    release = [t + imp.delay(t, DOWN, 2, 0, k) for k, t in enumerate([0.0, 0.0001, 0.0002])]
    assert release == sorted(release)  # stream transport keeps order
    dg = Impairment(LinkSpec(latency=Dist(dist="constant", value=0.003)),
                    NetSpec(transport="datagram"), RandomStreams(3), 1)
    assert dg.arrival(1.0, UP, 2, 5, 7) == 1.0 + 0.003


def test_loss_follows_the_link_loss_process() -> None:
    spec = LossSpec(p=0.3)
    link = LinkSpec(latency=Dist(dist="constant", value=0.002), loss=spec)
    streams = RandomStreams(9)
    ref = _des_loss(RandomStreams(9), spec.p)
    drop = Impairment(link, NetSpec(transport="datagram", qos=0), streams, 2)
    resend = Impairment(link, NetSpec(transport="datagram", qos=1, qos1_timeout=0.05,
                                      max_retries=5), RandomStreams(9), 2)
    for k in range(200):
        lost = [ref(2, 0, k, a) for a in range(6)]
        d0 = drop.delay(0.0, UP, 2, 0, k)
        assert (d0 == math.inf) == lost[0]
        n_lost = next((a for a, x in enumerate(lost) if not x), 6)
        d1 = resend.delay(0.0, UP, 2, 0, k)
        expect = math.inf if n_lost == 6 else 0.002 + 0.05 * n_lost
        assert d1 == expect or abs(d1 - expect) < 1e-12
    assert drop.lost > 0 and resend.lost >= drop.lost


def test_stream_resends_after_the_des_doubling_rto() -> None:
    """Over ``stream`` a message lost ``a`` times waits ``rto·(2^a − 1)`` more (the DES's
    ``Links._stream_try`` resends try ``a`` after ``rto·2^a``), and one lost on every one
    of its ``max_retries + 1`` tries is gone. Messages far apart, so order adds nothing."""
    spec = LossSpec(p=0.5)
    link = LinkSpec(latency=Dist(dist="constant", value=0.002), loss=spec)
    ref = _des_loss(RandomStreams(4), spec.p)
    imp = Impairment(link, NetSpec(transport="stream", rto=0.1, max_retries=3),
                     RandomStreams(4), 1)
    seen = set()
    for k in range(300):
        t = 10.0 * k
        lost = [ref(2, 0, k, a) for a in range(4)]
        n = next((a for a, x in enumerate(lost) if not x), 4)
        d = imp.delay(t, UP, 2, 0, k)
        if n == 4:
            assert d == math.inf
        else:
            assert d == pytest.approx(0.002 + 0.1 * (2**n - 1), abs=1e-9)
        seen.add(n)
    assert seen >= {0, 1, 2, 3}  # every case met


@pytest.mark.parametrize("up", [True, False])
def test_live_loses_the_messages_the_des_loses(up: bool) -> None:
    """Same seed, same packets lost: the shim's decision for (kind, subject, index,
    attempt) on a host link is the DES network's own (``Links.hop``), both directions
    (states up; triggers, keyed by the host's first node, and commands down)."""
    from sigma_des.net.kinds import COMMAND, STATE, TRIGGER

    sc = load(None, ["nodes=4", "hosts=2", "net.host_link.loss.p=0.2", "net.qos=0",
                     "net.transport='datagram'"])
    net = Network(Kernel(), sc.net_setup(), RandomStreams(sc.seed), lambda m: None)
    imp = Impairment(sc.net.host_link, NetSpec(transport="datagram", qos=0),
                     RandomStreams(sc.seed), 1)
    kinds = (STATE,) if up else (TRIGGER, COMMAND)
    n_lost = 0
    for kind in kinds:
        for node in (2, 3):  # host 1's nodes
            for frame in range(200):
                lost_des = net.hop(node, up, kind, node, frame, 0, 100, 0.0)[1]
                d = imp.delay(0.0, UP if up else DOWN, kind, node, frame)
                assert math.isinf(d) == lost_des
                n_lost += lost_des
    assert 40 * len(kinds) < n_lost < 120 * len(kinds)  # p = 0.2 of 400 per kind


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
    assert imp.arrival(0.001, UP, 2, 0, after) == 0.1
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
