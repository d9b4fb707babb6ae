"""The net layer's own specs: topology, link faults, the setup a scenario builds, and a
network driven from a hand-made setup (no scenario at all)."""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import pytest

from sigma_des import load
from sigma_des.core.rng import RandomStreams
from sigma_des.core.sim import Kernel
from sigma_des.errors import ConfigError
from sigma_des.net.kinds import COMMAND, STATE
from sigma_des.net.message import Msg
from sigma_des.net.network import Network
from sigma_des.net.spec import (
    BrokerSpec,
    DdsSpec,
    LinkDegrade,
    NetSetup,
    NetSpec,
    Topology,
)


def test_topology_links_and_validation() -> None:
    topo = Topology(nodes=3, hosts=2, host_of=(0, 1, 1))
    assert topo.server == 3
    assert topo.link_of == [0, 1, 1, 2]  # the server's link comes after the hosts'
    with pytest.raises(ConfigError, match=r"hosts: must be in 1\.\.nodes \(3\), got 4"):
        Topology(nodes=3, hosts=4, host_of=(0, 1, 2))
    with pytest.raises(ConfigError, match="host_of: must name a host for each of the 3"):
        Topology(nodes=3, hosts=2, host_of=(0, 1))
    with pytest.raises(ConfigError, match=r"host_of\[2\]: must be in 0\.\.1, got 2"):
        Topology(nodes=3, hosts=2, host_of=(0, 1, 2))
    with pytest.raises(ConfigError, match=r"extra_loss: must be in \[0, 1\)"):
        LinkDegrade(host=0, start=0.0, end=1.0, extra_loss=1.0)


def test_scenario_builds_the_net_setup() -> None:
    sc = load(None, [
        "nodes=4", "hosts=2", "placement=block", "warmup=0.5", "duration=3",
        "faults=[{kind='degrade', host=1, start=1.0, end=2.0, extra_delay=0.01},"
        " {kind='drop', node=2, message='command', frame=7},"
        " {kind='crash', node=0, start=2.0}]",
    ])
    setup = sc.net_setup()
    assert setup.topology == Topology(4, 2, (0, 0, 1, 1))
    assert (setup.net, setup.broker, setup.dds) == (sc.net, sc.broker, sc.dds)
    assert (setup.warmup, setup.end) == (0.5, 3.0)
    assert setup.degrades == (LinkDegrade(1, 1.0, 2.0, 0.01, 0.0),)
    assert setup.drops == frozenset({(COMMAND, 2, 7)})


def test_network_from_a_hand_made_setup() -> None:
    """One node, defaults (stream, QoS 1, 0.25 ms links at 1 Gbit/s): a state reaches
    the server after uplink, publish + delivery service and downlink, exactly."""
    setup = NetSetup(NetSpec(), BrokerSpec(), DdsSpec(), Topology(1, 1, (0,)), 0.0, 1.0)
    k = Kernel()
    got: list[tuple[Any, ...]] = []

    def deliver(m: Msg) -> None:
        got.append((m.client, m.kind, m.subject, m.index, m.payload, m.t_pub, k.now))

    net = Network(k, setup, RandomStreams(1), deliver)
    k.at(0.125, net.publish, 0, STATE, 0, 3, "x", 150, (net.server,))
    k.run(until=1.0)
    spb = 8.0 / 1e9
    wire = net.wire_bytes(150)
    at_broker = (0.125 + wire * spb) + 0.00025
    depart = at_broker + 4e-6 + 3e-6
    at_server = (depart + wire * spb) + 0.00025
    assert got == [(1, STATE, 0, 3, "x", 0.125, at_server)]
    assert net.broker.busy == depart
    assert net.broker_work == depart - at_broker


def test_net_imports_only_downward() -> None:
    """No net module imports the scenario, the engines or the aircraft."""
    net_dir = Path(__file__).resolve().parents[2] / "sigma_des" / "net"
    banned = ("sigma_des.config", "sigma_des.specs", "sigma_des.peer_specs", "sigma_des.api",
              "sigma_des.cli", "sigma_des.events", "sigma_des.agents", "sigma_des.metrics")
    found = []
    for path in sorted(net_dir.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            found += [(path.name, m) for m in names if m.startswith(banned)]
    assert found == []
