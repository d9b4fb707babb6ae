"""Bundled, over a lossy stream, live and the simulation lose the same tries.

The live server and hosts with ``--bundle`` run on one virtual clock beside the DES with
``deployment.bundle`` (the harness of ``test_equivalence.py``: the processes' link shims
carry the links' latency and loss). A bundle's loss draws are keyed by its place among
its host's bundles of its frame or tick (:mod:`sigma_des.net.bundlekeys`), counted by
sender and receiver on each side: the two lose, resend and give up the same tries. Here
both pack the same records into each bundle (constant step times); what this catches is
a key restated on one side only (live keyed the server's command bundles by the host's
index, not its first node, and lost other tries). That the key does not depend on which
records a bundle holds is ``tests/net/test_bundlekeys.py``'s.
"""

from __future__ import annotations

import pytest

from sigma_des import load
from sigma_des.config import Scenario
from sigma_des.live.broker import BrokerAddress
from sigma_des.live.host import Host
from sigma_des.live.loop import VirtualLoop
from sigma_des.live.wire import Topics
from tests.events.test_equivalence import LOSSY, METHODS, SETS, VirtualLiveServer, _Wire, run_des


def _run_live_bundled(sc: Scenario, method: str) -> tuple[VirtualLiveServer, list[Host]]:
    """The live server and hosts, bundling, on one virtual clock; the shims carry the
    links (the wire adds no time)."""
    loop = VirtualLoop()
    wire = _Wire(loop)
    topics = Topics("eqb")
    cfg = {"qos": 1, "impair": True, "step_delay": True, "max_inflight": 0, "bundle": True}
    addr = BrokerAddress("127.0.0.1", 1)  # never connected: the wire stands in
    srv = VirtualLiveServer(sc, method, wire.factory(0.0), topics, 1, True, bundle=True,
                            loop=loop)
    srv.triggers, srv.ticks = [], []
    hosts = [Host(sc, method, h, cfg, topics, addr, 0.0, client_factory=wire.factory(0.0),
                  loop=loop) for h in range(sc.hosts)]
    srv.start()
    loop.run(until=sc.duration)
    return srv, hosts


@pytest.mark.parametrize("method", METHODS)
def test_bundled_live_over_a_lossy_stream_loses_what_the_des_loses(method: str) -> None:
    sc = load(None, [*SETS, *LOSSY, "deployment.bundle=true"])
    live, hosts = _run_live_bundled(sc, method)
    des = run_des(sc, method)
    shims = [live.impair] + [h.impair for h in hosts]
    assert sum(s.resent for s in shims) == des.net.retransmissions > 20
    assert sum(s.gave_up for s in shims) == des.net.gave_up
    assert sum(s.lost for s in shims) == des.net.retransmissions + des.net.gave_up
