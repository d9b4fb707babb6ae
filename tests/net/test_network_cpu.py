"""Bursts, per-host clients and bundles on the network (net/network.py, net/broker.py)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest

from sigma_des import load
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.net.kinds import COMMAND, STATE, TRIGGER
from sigma_des.net.message import Msg
from sigma_des.net.network import Network

P, D, L = 3e-4, 2e-4, 1e-4  # broker publish and delivery service, link latency (s)
BASE = ["net.qos=0", "net.transport='datagram'", f"net.host_link.latency={L}",
        f"net.server_link.latency={L}", f"broker.publish_service={P}",
        f"broker.delivery_service={D}"]


def _net(overrides: list[str]) -> tuple[Kernel, Network, list[tuple[Any, ...]]]:
    got: list[tuple[Any, ...]] = []
    k = Kernel()

    def deliver(m: Msg) -> None:
        got.append((m.client, m.kind, m.subject, m.index, m.payload, k.now, m.t_pub,
                    m.t_recv))

    sc = load(None, [*BASE, *overrides])
    setup = replace(sc.net_setup(), warmup=0.0)
    return k, Network(k, setup, RandomStreams(sc.seed), deliver), got


def _two_states(net: Network) -> None:
    """Nodes 0 and 1 publish a state each at t = 0."""
    for i in (0, 1):
        net.publish(i, STATE, i, 7, f"s{i}", 150, (net.server,))


def test_broker_holding_the_one_core_delays_the_servers_receive_exactly() -> None:
    ds = 5e-5
    k0, net0, got0 = _net(["nodes=2", "hosts=2"])
    _two_states(net0)
    k0.env.run()
    k1, net1, got1 = _net(["nodes=2", "hosts=2", "deployment.preset='colocated'",
                           "deployment.cores=1", f"deployment.server_demand={ds}"])
    _two_states(net1)
    k1.env.run()
    # without a CPU stage the server has node 0's state when it arrives ...
    arrive = got0[0][5]
    # ... with one core, the broker still serves node 1's state (publish + delivery)
    # when node 0's arrives at the server, and holds the core until it is done
    broker_done = net1.broker.busy
    assert broker_done > arrive  # the case is what it claims (L < P + D)
    assert got1[0][5] == broker_done + ds
    ser = net1.wire_bytes(150) * 8 / 1e9  # the state's serialization onto the server link
    assert got1[0][5] - arrive == pytest.approx(P + D - L - ser + ds, rel=1e-9)
    # node 1's state: behind node 0's burst on the server's thread
    assert got1[1][5] == max(got0[1][5], got1[0][5]) + ds
    rep = net1.cpu_report()
    assert rep is not None
    server = rep.processes[1]
    assert server.bursts == 2 and server.busy == pytest.approx(2 * ds, rel=1e-12)


def test_publish_burst_delays_the_packet_by_the_demand() -> None:
    dh = 2.5e-4
    k0, net0, got0 = _net(["nodes=1", "hosts=1"])
    net0.publish(0, STATE, 0, 1, None, 150, (net0.server,))
    k0.env.run()
    k1, net1, got1 = _net(["nodes=1", "hosts=1", "deployment.preset='dedicated'",
                           f"deployment.host_demand={dh}"])
    net1.publish(0, STATE, 0, 1, None, 150, (net1.server,))
    assert k1.peek() == dh  # the PUBLISH leaves at the end of the host's burst
    k1.env.run()
    assert got1[0][5] - got0[0][5] == pytest.approx(dh, rel=1e-9)


def test_host_clients_get_one_trigger_delivery_per_host_handed_to_every_node() -> None:
    k, net, got = _net(["nodes=6", "hosts=2", "deployment.clients='host'"])
    net.publish(net.server, TRIGGER, net.server, 3, (3, None), 64, list(range(6)))
    k.env.run()
    # the broker: one publish part and H = 2 delivery parts (not N = 6)
    assert net.broker.work == pytest.approx(P + 2 * D, rel=1e-12)
    assert [g[0] for g in got] == [0, 1, 2, 3, 4, 5]  # every node, host by host, in order
    assert {g[2] for g in got} == {0, 1, 2, 3, 4, 5}  # each handed over as its own subject
    # the nodes of one host get it at the same instant; host 1's after one more delivery part
    t = [g[5] for g in got]
    assert t[0] == t[1] == t[2] and t[3] == t[4] == t[5]
    assert t[3] - t[0] == pytest.approx(D, rel=1e-9)
    # node-per-client: N = 6 deliveries
    k2, net2, got2 = _net(["nodes=6", "hosts=2"])
    net2.publish(net2.server, TRIGGER, net2.server, 3, (3, None), 64, list(range(6)))
    k2.env.run()
    assert net2.broker.work == pytest.approx(P + 6 * D, rel=1e-12)


def test_host_clients_send_a_command_to_its_node_through_the_host() -> None:
    k, net, got = _net(["nodes=6", "hosts=2", "deployment.clients='host'"])
    net.publish(net.server, COMMAND, 4, 9, "cmd", 96, (4,))
    k.env.run()
    assert [(g[0], g[1], g[2], g[3], g[4]) for g in got] == [(4, COMMAND, 4, 9, "cmd")]
    # it travelled on host 1's link (down), host 0's carried nothing
    links = {ld.name: ld.packets for ld in net.links()}
    assert links["host1.down"] == 1 and links["host0.down"] == 0


def test_bundle_one_publish_per_host_and_instant() -> None:
    k, net, got = _net(["nodes=6", "hosts=2", "deployment.clients='host'",
                        "deployment.bundle=true"])
    for i in (0, 1, 2, 4):
        net.publish(i, STATE, i, 5, f"s{i}", 150, (net.server,))
    k.at(1.0, net.publish, 0, STATE, 0, 6, "late", 150, (net.server,))
    k.env.run()
    links = {ld.name: ld.packets for ld in net.links()}
    assert links["host0.up"] == 2  # nodes 0-2 at t = 0 in one PUBLISH, node 0 at t = 1
    assert links["host1.up"] == 1
    assert links["server.down"] == 3
    # the broker served three PUBLISHes with one delivery each
    assert net.broker.work == pytest.approx(3 * (P + D), rel=1e-12)
    # the server's application gets every state, record by record, in publish order
    # (host 1's one-record PUBLISH is shorter on the wire: it arrives first)
    assert [(g[2], g[3], g[4]) for g in got] == [
        (4, 5, "s4"), (0, 5, "s0"), (1, 5, "s1"), (2, 5, "s2"), (0, 6, "late")]
    assert got[1][5] == got[2][5] == got[3][5] > got[0][5]


def test_bundle_takes_the_publishes_made_while_the_host_process_is_busy() -> None:
    """The loop-turn rule: node 0's state at t = 0 leaves at once (its burst holds the
    host's thread for ``dh``); nodes 1 and 2 publish during that burst, so they leave
    together when the thread is free, at ``dh``, in one burst. Their publish time (where
    the latency starts) is that burst's start, as live stamps the records of the turn
    that sends them."""
    dh = 1e-3
    k, net, got = _net(["nodes=3", "hosts=1", "deployment.clients='host'",
                        "deployment.bundle=true", "deployment.preset='dedicated'",
                        f"deployment.host_demand={dh}", "broker.publish_service=0.0",
                        "broker.delivery_service=0.0"])
    net.publish(0, STATE, 0, 5, "s0", 150, (net.server,))
    k.at(0.4 * dh, net.publish, 1, STATE, 1, 5, "s1", 150, (net.server,))
    k.at(0.8 * dh, net.publish, 2, STATE, 2, 5, "s2", 150, (net.server,))
    k.env.run()
    links = {ld.name: ld.packets for ld in net.links()}
    assert links["host0.up"] == 2
    cpu = net.cpu
    assert cpu is not None
    assert cpu.hosts[0].free == pytest.approx(2 * dh, abs=1e-15)  # two bursts, back to back
    assert [(g[2], g[6]) for g in got] == [(0, 0.0), (1, dh), (2, dh)]
    # the second PUBLISH left at 2 dh: its records arrive together, one PUBLISH later
    assert got[1][5] == got[2][5] > got[0][5]


def _three_states_one_host(extra: list[str]) -> tuple[Network, list[tuple[Any, ...]]]:
    """One host of 3 nodes, bundling, ``dh`` = 1 ms a burst and ``ds`` = 0.5 ms at the
    server: node 0 publishes at 0, nodes 1 and 2 during its burst (0.4 and 0.8 ms)."""
    k, net, got = _net(["nodes=3", "hosts=1", "deployment.clients='host'",
                        "deployment.bundle=true", "deployment.preset='dedicated'",
                        "deployment.host_demand=1e-3", "deployment.server_demand=5e-4",
                        "broker.publish_service=0.0", "broker.delivery_service=0.0", *extra])
    net.publish(0, STATE, 0, 5, "s0", 150, (net.server,))
    k.at(0.4e-3, net.publish, 1, STATE, 1, 5, "s1", 150, (net.server,))
    k.at(0.8e-3, net.publish, 2, STATE, 2, 5, "s2", 150, (net.server,))
    k.env.run()
    return net, got


def test_a_bundle_costs_its_demand_plus_a_record_cost_per_further_record() -> None:
    """``host_record``/``server_record``: the three-record case of the test above with
    ``dr`` per further record. Node 0's lone state: a burst of ``dh`` at the host, then
    ``ds`` at the server. The bundle of nodes 1 and 2 (two records): ``dh + dr`` at the
    host (from ``dh`` to ``2 dh + dr``), ``ds + dr_s`` at the server."""
    dh, dr, ds, drs = 1e-3, 3e-4, 5e-4, 2e-4
    net, got = _three_states_one_host([f"deployment.host_record={dr}",
                                       f"deployment.server_record={drs}"])
    cpu = net.cpu
    assert cpu is not None
    assert cpu.hosts[0].free == pytest.approx(2 * dh + dr, abs=1e-15)
    # the bundle's records reach the server's application at the end of its burst
    assert cpu.server.free == pytest.approx(got[2][5], abs=1e-15)
    rep = net.cpu_report()
    assert rep is not None
    busy = {pr.name: pr.busy for pr in rep.processes}
    assert busy["host0"] == pytest.approx(2 * dh + dr, rel=1e-12)
    assert busy["server"] == pytest.approx(2 * ds + drs, rel=1e-12)
    # without record costs the same run is cheaper by exactly one record on each side
    net0, _ = _three_states_one_host([])
    assert net0.cpu is not None and net0.cpu.hosts[0].free == pytest.approx(2 * dh, abs=1e-15)


def test_a_publish_waiting_for_its_thread_is_stamped_when_the_thread_starts_it() -> None:
    """Two states of one host at t = 0: the second waits ``dh`` for the host's thread.
    Live stamps a message when its handler runs, so its publish time (where its latency
    starts) is the burst's start, ``dh``; the first's is 0. Both arrive one burst apart."""
    dh = 1e-3
    k, net, got = _net(["nodes=2", "hosts=1", "deployment.preset='dedicated'",
                        f"deployment.host_demand={dh}", "broker.publish_service=0.0",
                        "broker.delivery_service=0.0"])
    _two_states(net)
    k.env.run()
    assert [(g[2], g[6]) for g in got] == [(0, 0.0), (1, dh)]
    assert got[1][5] - got[0][5] == pytest.approx(dh, rel=1e-9)


@pytest.mark.parametrize("switch", [0.005, 0.0005])
def test_a_publish_of_a_busy_process_leaves_when_it_waits_or_switches(switch: float) -> None:
    """``lock_switch``: two states of one host at t = 0, bursts of ``dh`` = 1 ms back to
    back. The first's burst ends at ``dh`` with the thread busy until ``2·dh``: with a
    5 ms switch it waits for the thread and both leave at ``2·dh``, in publish order
    (one serialization apart); with a 0.5 ms switch it leaves at ``dh + 0.5 ms`` and the
    second at its own burst's end. Without a switch (the default) each leaves at its
    burst's end."""
    dh = 1e-3
    over = ["nodes=2", "hosts=1", "deployment.preset='dedicated'",
            f"deployment.host_demand={dh}", "broker.publish_service=0.0",
            "broker.delivery_service=0.0"]
    k0, net0, got0 = _net(over)
    _two_states(net0)
    k0.env.run()
    k, net, got = _net([*over, f"deployment.lock_switch={switch}"])
    _two_states(net)
    k.env.run()
    assert got0[1][5] - got0[0][5] == pytest.approx(dh, abs=1e-12)  # one burst apart
    assert [g[2] for g in got] == [0, 1] and [g[6] for g in got] == [0.0, dh]
    first = min(2 * dh, dh + switch)
    assert got[0][5] - got0[0][5] == pytest.approx(first - dh, abs=1e-12)
    # leaving together, the second is serialized behind the first on the host link
    ser = net.wire_bytes(150) * 8 / 1e9
    behind = ser if switch > dh else 0.0
    assert got[1][5] - got0[1][5] == pytest.approx(behind, abs=1e-12)


def test_bundle_takes_the_servers_commands_of_one_instant_to_each_host() -> None:
    """Six nodes on two hosts: the server's six commands of one tick leave as two
    PUBLISHes, one per host client (live ``--bundle``), each delivered once and handed to
    its nodes record by record; a trigger is not bundled."""
    k, net, got = _net(["nodes=6", "hosts=2", "deployment.clients='host'",
                        "deployment.bundle=true"])
    for i in range(6):
        net.publish(net.server, COMMAND, i, 3, f"c{i}", 110, (i,))
    k.env.run()
    links = {ld.name: ld.packets for ld in net.links()}
    assert links["server.up"] == 2
    assert links["host0.down"] == 1 and links["host1.down"] == 1
    assert net.broker.work == pytest.approx(2 * (P + D), rel=1e-12)
    # each node gets its own command (receiver = the node), host by host in node order
    assert sorted((g[0], g[2], g[4]) for g in got) == [(i, i, f"c{i}") for i in range(6)]
    # the two bundles' wire sizes: three 110-bit records each
    assert {ld.name: ld.bytes for ld in net.links()}["server.up"] == 2 * net.wire_bytes(330)


def test_bundle_wire_size_is_the_records_together() -> None:
    k, net, _got = _net(["nodes=3", "hosts=1", "deployment.clients='host'",
                         "deployment.bundle=true"])
    for i in range(3):
        net.publish(i, STATE, i, 5, None, 150, (net.server,))
    k.env.run()
    up = {ld.name: ld.bytes for ld in net.links()}["host0.up"]
    assert up == net.wire_bytes(3 * 150)


@pytest.mark.parametrize("switch", [0.005, 0.0005])
def test_copies_reaching_a_busy_process_are_read_in_batches(switch: float) -> None:
    """``lock_switch``: four states reach the server (demand ``ds`` = 1 ms, an idle
    thread at the first) at ``a0``, ``a0`` + 0.2, + 0.4 and + 1.5 ms. The first is read
    at once; the second opens a batch read when the thread frees (``a0 + ds``) or
    ``switch`` after it arrived, whichever is first; the third arrives before that and
    joins it; the fourth arrives after it and opens the next batch, read when the thread
    has handled the second and third (``a0 + 3 ds``) or at the switch. Without
    ``lock_switch`` each is read at its own burst's start (``a0 + k ds``)."""
    ds = 1e-3
    offs = (0.0, 2e-4, 4e-4, 1.5e-3)
    over = ["nodes=4", "hosts=4", "deployment.preset='dedicated'",
            f"deployment.server_demand={ds}", "broker.publish_service=0.0",
            "broker.delivery_service=0.0"]
    runs = {}
    for sw in (0.0, switch):
        k, net, got = _net([*over, f"deployment.lock_switch={sw}"])
        for i, t in enumerate(offs):
            k.at(t, net.publish, i, STATE, i, 5, None, 150, (net.server,))
        k.env.run()
        runs[sw] = {g[2]: g for g in got}
    a = [runs[0.0][i][7] - 0.0 for i in range(4)]  # without: read at the burst's start
    a0 = a[0]
    assert a[1:] == pytest.approx([a0 + ds, a0 + 2 * ds, a0 + 3 * ds], abs=1e-12)
    arrive = [a0 + t for t in offs]  # one link path each: the offsets carry over
    b1 = min(a0 + ds, arrive[1] + switch)
    b2 = min(a0 + 3 * ds, arrive[3] + switch)
    got = [runs[switch][i][7] for i in range(4)]
    assert got == pytest.approx([a0, b1, b1, b2], abs=1e-12)
    # the handling itself is unchanged: each copy reaches the server at its burst's end
    assert [runs[switch][i][5] for i in range(4)] == [runs[0.0][i][5] for i in range(4)]


def test_zero_demands_touch_nothing() -> None:
    _k, net, _got = _net(["nodes=2", "hosts=1", "deployment.preset='colocated'",
                          "broker.publish_service=0.0", "broker.delivery_service=0.0"])
    assert net.broker.process is None
    _two_states(net)
    net.k.env.run()
    cpu = net.cpu
    assert cpu is not None
    assert all(p.bursts == 0 and p.free == -math.inf for p in cpu.processes)
    assert cpu.machines[0].cores == [[], []]



@pytest.mark.parametrize("cores", [1, 2])
def test_two_hosts_receiving_at_the_same_instant_share_one_core(cores: int) -> None:
    """A trigger reaches hosts 0 and 1 at the same instant (equal links, instantaneous
    broker). On one core host 1's receive waits for host 0's: it ends exactly one
    demand later; on two cores both end together."""
    dh = 3e-4
    k, net, got = _net(["nodes=2", "hosts=2", "broker.publish_service=0.0",
                        "broker.delivery_service=0.0", "deployment.preset='colocated'",
                        f"deployment.cores={cores}", f"deployment.host_demand={dh}",
                        "deployment.server_demand=1e-4"])
    net.publish(net.server, TRIGGER, net.server, 0, (0, None), 64, [0, 1])
    k.env.run()
    t0, t1 = got[0][5], got[1][5]
    rep = net.cpu_report()
    assert rep is not None
    host0, host1 = rep.processes[2:]
    assert host0.max_wait == 0.0 and host0.busy == dh
    if cores == 1:
        assert t1 == t0 + dh
        assert host1.max_wait == pytest.approx(dh, rel=1e-9)
    else:
        assert t1 == t0 and host1.max_wait == 0.0


def test_a_network_thread_stamps_the_receipt_then_the_loop_handles_it() -> None:
    """Dedicated machines, zero broker services, two nodes on two hosts publish a state
    each at t = 0. Each host's loop burst is [0, dh); its network thread (idle: a wake-up,
    ``hn + hw``) writes it from ``dh`` on and the PUBLISH leaves at that burst's start,
    ``dh``, as without the thread, so both reach the server at the same ``A0``. The
    server's network thread (``sn`` a message, ``sw`` a wake-up) takes the first at once
    (busy until ``A0 + sn + sw``) and the second when it is free (no wake-up, busy ``sn``
    more). Each is stamped at its burst's end, where paho's callback runs, and the
    application gets it then (live's loop runs a state 1-3 µs after the stamp, at every
    load); the loop thread's burst (``ds``) follows and delays nothing of it."""
    dh, hn, hw, ds, sn, sw = 1e-3, 2e-4, 3e-4, 3e-4, 1e-4, 2e-4
    over = ["nodes=2", "hosts=2", "deployment.preset='dedicated'",
            f"deployment.host_demand={dh}", f"deployment.server_demand={ds}",
            "broker.publish_service=0.0", "broker.delivery_service=0.0"]
    k0, net0, got0 = _net(over)
    _two_states(net0)
    k0.env.run()
    k, net, got = _net([*over, f"deployment.host_net_msg={hn}", f"deployment.host_net_wake={hw}",
                        f"deployment.server_net_msg={sn}",
                        f"deployment.server_net_wake={sw}"])
    _two_states(net)
    k.env.run()
    a0 = got0[0][7]  # the arrival: stamped at once without a network thread either
    assert [g[2] for g in got] == [0, 1] and [g[6] for g in got] == [0.0, 0.0]
    stamps = [a0 + sn + sw, a0 + 2 * sn + sw]
    assert [g[7] for g in got] == pytest.approx(stamps, abs=1e-12)
    assert [g[5] for g in got] == pytest.approx(stamps, abs=1e-12)
    assert net.cpu is not None
    assert net.cpu.server.busy == pytest.approx(2 * sn + sw + 2 * ds, abs=1e-15)
    assert [h.busy for h in net.cpu.hosts] == pytest.approx([dh + hn + hw] * 2, abs=1e-15)


def _two_commands(extra: list[str], drops: frozenset[tuple[int, int, int]]
                  ) -> tuple[Kernel, Network, list[tuple[Any, ...]]]:
    """One node on one host (dedicated machines, zero broker services, a stream): the
    server publishes commands 7 and 8 to node 0 at t = 0; ``drops`` loses first tries."""
    got: list[tuple[Any, ...]] = []
    k = Kernel()

    def deliver(m: Msg) -> None:
        got.append((m.index, k.now, m.t_recv))

    sc = load(None, [*BASE, "net.transport='stream'", "nodes=1", "hosts=1",
                     "deployment.preset='dedicated'", "broker.publish_service=0.0",
                     "broker.delivery_service=0.0", *extra])
    setup = replace(sc.net_setup(), warmup=0.0, drops=drops)
    net = Network(k, setup, RandomStreams(sc.seed), deliver)
    for index in (7, 8):
        net.publish(net.server, COMMAND, 0, index, f"c{index}", 96, (0,))
    k.env.run()
    return k, net, got


def test_a_copy_held_behind_a_resent_one_was_read_at_its_own_arrival() -> None:
    """Command 7's first try to the host is lost: it arrives ``rto`` later (at ``A7 +
    rto``, its try leaving the broker ``rto`` after the first), and command 8, arriving
    at ``A8``, is held behind it. The host's network thread (``hn`` a message, ``hw`` a
    wake-up) reads 8 at ``A8`` (a wake-up: busy until ``A8 + hn + hw``) and the resent 7
    when it arrives (another wake-up); the loop gets 7 at once, then 8 (read long
    before), both at ``A7 + rto``: live's shim delays and resends a copy paho's thread
    has already read. Without the rule 8 would wait behind 7's read (``+ hn + hw``) and
    its own (``+ hn``)."""
    dh, hn, hw = 2e-4, 1e-4, 3e-4
    cpu = [f"deployment.host_demand={dh}", f"deployment.host_net_msg={hn}",
           f"deployment.host_net_wake={hw}"]
    _k0, _n0, ref = _two_commands(cpu, frozenset())
    a7 = ref[0][2] - hn - hw  # 7's first-try arrival: stamped after a wake-up's read
    assert a7 > 0.0
    _k, net, got = _two_commands(cpu, frozenset({(COMMAND, 0, 7)}))
    rto = load(None, []).net.rto
    assert [g[0] for g in got] == [7, 8]
    assert [g[1] for g in got] == pytest.approx([a7 + rto] * 2, abs=1e-12)
    assert [g[2] for g in got] == pytest.approx([a7 + rto] * 2, abs=1e-12)
    assert net.cpu is not None
    assert net.cpu.hosts[0].busy == pytest.approx(2 * (hn + hw) + 2 * dh, abs=1e-15)
