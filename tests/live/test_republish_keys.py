"""Live keys a republished state by the re-request it answers, as the simulation keys its
REPUBLISH: the link shim's draws and the collector's first-copy rule both see that
index, so every re-request's answer is a delivery of its own (with the frame as the key,
live counted only the first answer of a frame, and drew later answers' delays with the
newest re-request's key). No broker: the server runs on a virtual loop and the test
hands it the host's payloads."""

from __future__ import annotations

from typing import Any

import numpy as np

from sigma_des import load
from sigma_des.live.loop import VirtualLoop
from sigma_des.live.server import LiveServer
from sigma_des.live.shim import DOWN
from sigma_des.live.wire import Topics, encode_state
from sigma_des.net.kinds import REPUBLISH, STATE, rerequest_index


class _Client:
    def __init__(self, subs: list[tuple[str, int]], on_message: Any) -> None:
        self.on_message = on_message
        self.connects, self.disconnects = 1, 0

    def publish(self, topic: str, payload: bytes, qos: int) -> None:
        pass


class _Shim:
    """A lossless link that delays every message by 2 ms and notes its key."""

    lost = resent = gave_up = 0

    def __init__(self) -> None:
        self.keys: list[tuple[int, int, int]] = []

    def arrival(self, t: float, direction: int, kind: int, subject: int, index: int) -> float:
        if direction == DOWN:
            self.keys.append((kind, subject, index))
        return t + 0.002


def test_each_reanswer_is_keyed_and_counted_by_its_rerequest() -> None:
    sc = load(None, ["nodes=4", "hosts=2", "warmup=0", "duration=1"])
    loop = VirtualLoop()
    topics = Topics("t")
    srv = LiveServer(sc, "lockstep", _Client, topics, 1, False, loop=loop)
    srv.impair = shim = _Shim()  # type: ignore[assignment]
    srv.start()
    loop.run(until=0.02)  # trigger 0 issued; the barrier waits for its states
    assert srv.latest_trigger == 0
    r0, r1 = rerequest_index(0, 0), rerequest_index(0, 1)
    srv.rerequest(1, 0, 0)
    srv.rerequest(1, 0, 1)  # the newest re-request is now r1
    obs = np.zeros(12)
    t = loop.now
    sends = [encode_state(1, 0, t, t, 0.0, 0, obs),  # the state itself, late
             encode_state(1, 0, t, t, 0.0, 0, obs, republish=True, index=r0),
             encode_state(1, 0, t, t, 0.0, 0, obs, republish=True, index=r1),
             encode_state(1, 0, t, t, 0.0, 0, obs, republish=True, index=r1)]  # a copy
    for payload in sends:
        srv.client.on_message(topics.state(0), payload)
    loop.run(until=t + 0.01)
    # the answer to r0 keyed by r0, not by the newest re-request (r1)
    assert shim.keys == [(STATE, 1, 0), (REPUBLISH, 1, r0), (REPUBLISH, 1, r1),
                         (REPUBLISH, 1, r1)]
    lat = srv.collector.latencies("state")
    # the state and one answer to each re-request, each 2 ms; the copy of r1's is not
    new = lat[-3:]
    np.testing.assert_allclose(new, [0.002, 0.002, 0.002])
    assert srv.collector.duplicates >= 1
