"""Live ``--bundle`` keys its PUBLISHes by the simulation's rule (net/bundlekeys.py): the
host's bundles of states as sent, the server's on receipt, the server's command bundles
as sent and the host's on receipt, each equal to the simulation's key of the same bundle
(its publisher → broker and broker → receiver hops). No broker: the processes run on one
virtual loop, their messages handed over by the test, their link shims replaced by one
that only notes the keys."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from sigma_des import load
from sigma_des.live.broker import BrokerAddress
from sigma_des.live.host import Host
from sigma_des.live.loop import VirtualLoop
from sigma_des.live.server import LiveServer
from sigma_des.live.shim import DOWN, UP
from sigma_des.live.wire import Topics
from sigma_des.net.bundlekeys import BUNDLE_SLOTS as S
from sigma_des.net.kinds import COMMAND, REPUBLISH, STATE
from tests.net.bundle_net import SERVER, R, bundles, traffic

Key = tuple[int, int, int]


class _Client:
    """A client that keeps what is published and its ``on_message``."""

    def __init__(self, subs: list[tuple[str, int]], on_message: Callable[..., Any]) -> None:
        self.on_message = on_message
        self.published: list[tuple[str, bytes]] = []
        self.connects, self.disconnects = 1, 0

    def publish(self, topic: str, payload: bytes, qos: int) -> None:
        self.published.append((topic, payload))


class _Shim:
    """The link shim of a lossless, instant link that notes each message's key."""

    lost = resent = gave_up = 0

    def __init__(self) -> None:
        self.keys: list[tuple[int, int, int, int]] = []

    def arrival(self, t: float, direction: int, kind: int, subject: int, index: int) -> float:
        self.keys.append((direction, kind, subject, index))
        return t

    def of(self, direction: int, kinds: tuple[int, ...]) -> list[Key]:
        return [k[1:] for k in self.keys if k[0] == direction and k[1] in kinds]


def _live() -> tuple[list[Key], list[Key], list[Key], list[Key]]:
    """The live processes (the server and host 0 of :data:`SETS`' six nodes) send the
    bundles of :func:`~tests.net.bundle_net.traffic` (host 0's states; the server's
    commands); the keys of: host 0's state bundles sent, the server's received, the
    server's command bundles sent, host 0's received."""
    sc = load(None, ["nodes=6", "hosts=2"])
    loop = VirtualLoop()
    topics = Topics("t")
    srv = LiveServer(sc, "none", _Client, topics, 1, False, bundle=True, loop=loop)
    cfg = {"qos": 1, "impair": False, "step_delay": False, "max_inflight": 0, "bundle": True}
    host = Host(sc, "none", 0, cfg, topics, BrokerAddress("127.0.0.1", 1), 0.0,
                client_factory=_Client, loop=loop)
    srv.impair = s_shim = _Shim()  # type: ignore[assignment]
    host.impair = h_shim = _Shim()  # type: ignore[assignment]
    assert isinstance(srv.client, _Client) and isinstance(host.client, _Client)
    srv.start()
    loop.run(until=0.5)  # triggers up to frame 6 and beyond issued: the states are due
    assert srv.latest_trigger >= 6
    srv.rerequest(1, 5, 0)  # the server asks node 1 again for frame 5 (index R)
    obs = np.zeros(12)

    def turn(*states: tuple[int, int, bool]) -> None:
        """Host 0's nodes publish ``(node, frame, republish)`` in one loop turn."""
        t = loop.now
        for j, frame, rep in states:
            host.send_state(j, (frame, t, obs, None), t, rep, R if rep else -1)
        loop.run(until=t + 1e-3)

    turn((0, 5, False), (1, 5, False))
    turn((2, 5, False))
    turn((1, 5, True))
    turn((2, 6, False), (0, 6, False))
    width = host.cmd.shape[1]
    srv.publish_commands(3, 0, np.arange(6), np.zeros((6, width)))
    srv.publish_commands(3, 0, np.array([1, 4]), np.zeros((6, width)))
    for topic, payload in host.client.published:  # host 0's states reach the server
        if topic == topics.state(0):
            srv.client.on_message(topic, payload)
    for topic, payload in srv.client.published:  # host 0's commands reach it
        if topic == topics.cmd(0):
            host.client.on_message(topic, payload)
    loop.run(until=loop.now + 1e-3)
    states = (STATE, REPUBLISH)
    return (h_shim.of(UP, states), s_shim.of(DOWN, states), s_shim.of(UP, (COMMAND,)),
            h_shim.of(DOWN, (COMMAND,)))


def test_live_bundles_are_keyed_as_the_simulations() -> None:
    host_sent, srv_got, srv_sent, host_got = _live()
    # by hand: (kind, the host's first node, index * 1024 + the bundle's place)
    assert host_sent == [(STATE, 0, 5 * S), (STATE, 0, 5 * S + 1), (REPUBLISH, 0, R * S),
                         (STATE, 0, 6 * S)]
    assert srv_got == host_sent  # nothing lost: the server counts as the host did
    # host 1's first node is 3 (not its index 1)
    assert srv_sent == [(COMMAND, 0, 3 * S), (COMMAND, 3, 3 * S), (COMMAND, 0, 3 * S + 1),
                        (COMMAND, 3, 3 * S + 1)]
    assert host_got == [(COMMAND, 0, 3 * S), (COMMAND, 0, 3 * S + 1)]
    # the simulation's keys of the same bundles, hop by hop
    net, _got = traffic()
    ups, downs = bundles(net.ups), bundles(net.downs)
    assert host_sent == [u[1:4] for u in ups if u[0] == 0]
    assert srv_got == [d[1:4] for d in downs if d[0] == SERVER and d[2] == 0]
    assert srv_sent == [u[1:4] for u in ups if u[0] == SERVER]
    assert host_got == [d[1:4] for d in downs if d[0] == 0]
