"""A network that records the draw key of every try of every hop (the bundle key tests)."""

from __future__ import annotations

from dataclasses import replace

from sigma_des import load
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.kinds import COMMAND, REPUBLISH, STATE, rerequest_index
from sigma_des.net.message import Msg
from sigma_des.net.network import Bundle, Network

#: one hop's try: (client, kind, subject, index, attempt, the first record's key or None)
Try = tuple[int, int, int, int, int, tuple[int, int, int] | None]


def _try(m: Msg) -> Try:
    first = tuple(m.payload[0][:3]) if isinstance(m.payload, Bundle) else None
    return (m.client, m.kind, m.subject, m.index, m.attempt, first)  # type: ignore[return-value]


class KeyedNet(Network):
    """:class:`Network` noting each publisher → broker try (``ups``) and each broker →
    receiver try (``downs``) as it leaves, and each delivery to an application
    (``got``: receiver, kind, subject, index)."""

    ups: list[Try]
    downs: list[Try]

    def _publish_try(self, m: Msg) -> None:
        self.ups.append(_try(m))
        super()._publish_try(m)

    def _deliver_try(self, m: Msg) -> None:
        self.downs.append(_try(m))
        super()._deliver_try(m)


def keyed_net(overrides: list[str]) -> tuple[Kernel, KeyedNet, list[tuple[int, ...]]]:
    """A :class:`KeyedNet` of the scenario ``overrides`` (metrics from t = 0) on a fresh
    kernel, and the list its deliveries are noted in."""
    got: list[tuple[int, ...]] = []
    k = Kernel()

    def deliver(m: Msg) -> None:
        got.append((m.client, m.kind, m.subject, m.index))

    sc = load(None, overrides)
    net = KeyedNet(k, replace(sc.net_setup(), warmup=0.0), RandomStreams(sc.seed), deliver)
    net.ups, net.downs = [], []
    return k, net, got


def bundles(tries: list[Try]) -> list[Try]:
    """The tries that carry a bundle."""
    return [t for t in tries if t[5] is not None]


#: 6 nodes, hosts 0 (nodes 0-2, client 0) and 1 (nodes 3-5, client 3), the server is 6;
#: constant latencies, no broker time, no loss
SETS = ["nodes=6", "hosts=2", "deployment.clients='host'", "deployment.bundle=true",
        "net.qos=0", "net.transport='datagram'", "net.host_link.latency=1e-4",
        "net.server_link.latency=1e-4", "broker.publish_service=0.0",
        "broker.delivery_service=0.0"]
SERVER = 6
R = rerequest_index(5, 0)  # 320


def traffic(extra: list[str] | None = None) -> tuple[KeyedNet, list[tuple[int, ...]]]:
    """:data:`SETS` (and ``extra``): host 0 sends frame 5 in two bundles (nodes 0 and 1
    at t = 0, node 2 at 1 ms), node 1's republish of frame 5 (re-request 320) at 2 ms and
    frame 6 (nodes 2 and 0) at 3 ms; host 1 sends frame 5 (node 4) at 0. The server sends
    tick 3's commands to all six nodes at 4 ms and again to nodes 1 and 4 at 5 ms."""
    k, net, got = keyed_net([*SETS, *(extra or [])])
    sub = (SERVER,)
    for i in (0, 1):
        net.publish(i, STATE, i, 5, None, 150, sub)
    net.publish(4, STATE, 4, 5, None, 150, sub)
    k.at(1e-3, net.publish, 2, STATE, 2, 5, None, 150, sub)
    k.at(2e-3, net.publish, 1, REPUBLISH, 1, R, None, 150, sub)
    for i in (2, 0):
        k.at(3e-3, net.publish, i, STATE, i, 6, None, 150, sub)
    for i in range(6):
        k.at(4e-3, net.publish, SERVER, COMMAND, i, 3, None, 110, (i,))
    for i in (1, 4):
        k.at(5e-3, net.publish, SERVER, COMMAND, i, 3, None, 110, (i,))
    k.env.run()
    return net, got
