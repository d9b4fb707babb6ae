"""An external broker's ACL keeps a client without rights to the control topics from
stopping a run (docs/howto/live.md, "With a broker of your own")."""

from __future__ import annotations

import threading
import time

import pytest

from sigma_des.live.broker import Broker, BrokerAddress
from sigma_des.live.loop import Client
from sigma_des.live.runner import LiveOptions, run_live
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import Topics, encode_trigger
from tests.live.live_helpers import live_scenario, needs_mosquitto

pytestmark = needs_mosquitto

GUEST_PW = "guest-password"


def _acl(sim: str, guest_rights: str) -> str:
    """The how-to's ACL: the simulator's user reads and writes ``sd/#``; the guest has
    ``guest_rights`` on it (``read``: an observer)."""
    return f"user {sim}\ntopic readwrite sd/#\n\nuser guest\ntopic {guest_rights} sd/#\n"


def _guest_stops_the_run(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
    """The guest publishes ``stop`` and a forged trigger, from a thread of its own (the
    server's loop goes on meanwhile)."""
    threading.Thread(target=_guest, args=(addr, tp)).start()


def _guest(addr: BrokerAddress, tp: Topics) -> None:
    c = Client(BrokerAddress(addr.host, addr.port, "guest", GUEST_PW), "guest", [],
               lambda t, p: None)
    c.start()
    c.publish(tp.ctl, b"stop", 1)
    c.publish(tp.trig, encode_trigger(140, 0.0, 0.01, float("-inf"), 0), 1)
    time.sleep(0.3)
    c.stop()


@pytest.mark.parametrize("rights", ["read", "readwrite"])
def test_a_client_without_rights_to_the_control_topic_cannot_stop_a_run(rights: str) -> None:
    b = Broker(users={"guest": GUEST_PW}, acl="")
    b.acl = _acl(b.username, rights)
    with b as addr:
        opts = LiveOptions(broker=f"{addr.host}:{addr.port}", username=addr.username,
                           password=addr.password, hook=_guest_stops_the_run)
        res, _m, _ = run_live(live_scenario(), ["none"], opts)
    live, m = res.live["none"], res.methods["none"]
    if rights == "read":  # the broker dropped the guest's stop: the run went to its end
        assert live["hosts_reported"] == [0, 1]
        assert m["missed_frac"] < 0.5 and m["rejected"] == 0  # nor did its trigger arrive
    else:  # the control case: with write rights the guest's stop ends the hosts' run
        assert live["hosts_reported"] == []
        assert m["missed_frac"] > 0.5
