"""A bundle's hops draw by its place among its host's bundles (net/network.py with
net/bundlekeys.py): counted by the sender for the publisher → broker hop, at the broker's
fan-out for the broker → receiver hop; unbundled messages keep their own keys."""

from __future__ import annotations

from sigma_des.core.rng import RandomStreams
from sigma_des.net.bundlekeys import BUNDLE_SLOTS
from sigma_des.net.kinds import COMMAND, REPUBLISH, STATE
from tests.net.bundle_net import SERVER, R, bundles, traffic

S = BUNDLE_SLOTS


def test_bundles_of_one_frame_count_0_1_and_both_hops_agree_without_loss() -> None:
    net, got = traffic()
    ups = bundles(net.ups)
    # (client, kind, host's first node, index * 1024 + j, attempt, first record)
    assert ups == [
        (0, STATE, 0, 5 * S, 0, (STATE, 0, 5)),
        (3, STATE, 3, 5 * S, 0, (STATE, 4, 5)),
        (0, STATE, 0, 5 * S + 1, 0, (STATE, 2, 5)),
        (0, REPUBLISH, 0, R * S, 0, (REPUBLISH, 1, R)),
        (0, STATE, 0, 6 * S, 0, (STATE, 2, 6)),
        (SERVER, COMMAND, 0, 3 * S, 0, (COMMAND, 0, 3)),
        (SERVER, COMMAND, 3, 3 * S, 0, (COMMAND, 3, 3)),
        (SERVER, COMMAND, 0, 3 * S + 1, 0, (COMMAND, 1, 3)),
        (SERVER, COMMAND, 3, 3 * S + 1, 0, (COMMAND, 4, 3)),
    ]
    # nothing lost: the receivers count as the senders did (states to the server,
    # commands to the host clients 0 and 3; host 1's shorter bundle reaches the broker
    # first, each host's bundles come in their order)
    to = [SERVER] * 5 + [0, 3, 0, 3]
    assert sorted(bundles(net.downs)) == sorted(
        (c, *u[1:]) for c, u in zip(to, ups, strict=True))
    # the records inside keep their own keys
    assert [g for g in got if g[0] == SERVER] == [
        (SERVER, STATE, 4, 5), (SERVER, STATE, 0, 5), (SERVER, STATE, 1, 5),
        (SERVER, STATE, 2, 5), (SERVER, REPUBLISH, 1, R), (SERVER, STATE, 2, 6),
        (SERVER, STATE, 0, 6)]
    assert sorted(g for g in got if g[0] != SERVER) == sorted(
        [(i, COMMAND, i, 3) for i in range(6)] + [(1, COMMAND, 1, 3), (4, COMMAND, 4, 3)])


def test_unbundled_messages_keep_their_own_keys() -> None:
    net, _got = traffic(["deployment.bundle=false"])
    assert bundles(net.ups) == [] and bundles(net.downs) == []
    # each state and command on its own, keyed (kind, node, index)
    assert sorted(u[1:4] for u in net.ups) == sorted(
        [(STATE, i, 5) for i in (0, 1, 4, 2)] + [(REPUBLISH, 1, R)]
        + [(STATE, i, 6) for i in (2, 0)] + [(COMMAND, i, 3) for i in (*range(6), 1, 4)])


def test_a_bundle_lost_for_good_upstream_is_not_counted_by_its_receiver() -> None:
    """QoS 0 over datagrams, host links lossy: frame 5's first bundle of host 0 (draw
    key (STATE, 0, 5120)) is lost on its way to the broker, its second (5121) is not
    (seed 1's uniforms of ``lossu.host.up``, ``p`` between the two). The server never
    sees the first, so it counts the second as its first of the frame: 5120 downstream."""
    u = RandomStreams(1).stream("lossu.host.up")
    u0, u1 = (float(u.uniform(STATE, 0, 5 * S + j, 0)[0]) for j in (0, 1))
    assert u0 < u1  # seed 1: the case is what it claims
    p = (u0 + u1) / 2
    net, got = traffic([f"net.host_link.loss.p={p}", "seed=1"])
    assert (0, STATE, 0, 5 * S, 0, (STATE, 0, 5)) in net.ups
    assert (0, STATE, 0, 5 * S + 1, 0, (STATE, 2, 5)) in net.ups
    host0 = [d for d in bundles(net.downs) if d[:3] == (SERVER, STATE, 0)]
    assert host0[0] == (SERVER, STATE, 0, 5 * S, 0, (STATE, 2, 5))
    assert (SERVER, STATE, 0, 5) not in got and (SERVER, STATE, 2, 5) in got


def test_a_drop_fault_on_a_bundles_first_record_drops_the_bundle() -> None:
    """A ``drop`` fault names a message; a bundle led by it loses its first try on the
    broker → receiver hop (QoS 0: gone), the other bundles arrive."""
    net, got = traffic(['faults=[{kind="drop", node=2, frame=5, message="state"}]'])
    states = [g[2:] for g in got if g[0] == SERVER and g[1] == STATE]
    assert sorted(states) == [(0, 5), (0, 6), (1, 5), (2, 6), (4, 5)]
