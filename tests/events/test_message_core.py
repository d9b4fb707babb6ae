"""The message core behind MethodRun (docs/concepts/engines.md): one interface, two cores."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.message_core import EventCore, MessageCore
from sigma_des.events.tap import Tap
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.metrics.reports import NetReport
from sigma_des.net.kinds import COMMAND, REREQUEST
from sigma_des.net.message import Msg
from tests.conftest import tiny


def _run(method: str = "none", compiled: bool = False, **over: Any) -> MethodRun:
    sc = replace(tiny(**over), engine="cohort" if compiled else "events")
    return MethodRun(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc),
                     compiled=compiled)


def test_both_cores_meet_the_interface() -> None:
    cores: list[MessageCore] = [_run().core, _run(compiled=True).core]
    assert isinstance(cores[0], EventCore) and isinstance(cores[1], CompiledCore)


def test_event_core_publishes_rerequests_and_commands_on_the_network() -> None:
    run = _run()
    got: list[Msg] = []
    run.net.deliver = got.append
    run.core.publish_rerequest(1, 7, 70)  # retries past 63 share the last index
    run.core.publish_commands(4, 3, np.array([2, 0]), np.arange(6.0).reshape(3, 2))
    run.kernel.run(until=1.0)
    rr = [m for m in got if m.kind == REREQUEST]
    assert [(m.client, m.subject, m.index, m.payload) for m in rr] == [(1, 1, 7 * 64 + 63, 7)]
    cmd = sorted((m for m in got if m.kind == COMMAND), key=lambda m: m.client)
    assert [(m.client, m.index, m.payload[0], m.payload[1].tolist()) for m in cmd] == [
        (0, 4, 3, [0.0, 1.0]), (2, 4, 3, [4.0, 5.0])]
    assert run.core.advance_to(0.5, True) is False  # nothing of its own to run


def test_write_back_hands_the_counters_over_once() -> None:
    """The compiled core's counters reach the network, collector, nodes and kernel
    through their hooks; a second hand-over adds nothing."""
    run = _run("lockstep", compiled=True, **{"net.transport": "datagram",
                                             "net.host_link.loss": {"p": 0.2}})
    out = run.run()
    net = NetReport.of(run.net)
    assert sum(b for _n, b, _p in net.links) > 0
    counts = (net, run.collector.messages, run.collector.duplicates,
              run.nodes.history_misses, run.kernel.events)
    run.core.write_back()
    assert counts == (NetReport.of(run.net), run.collector.messages,
                      run.collector.duplicates, run.nodes.history_misses, run.kernel.events)
    assert out["metrics"]["rerequests"] > 0  # the Lock-Step barrier mirror was exercised


class _Counting(Tap):
    def __init__(self) -> None:
        self.calls: dict[str, int] = {}

    def _count(self, name: str) -> None:
        self.calls[name] = self.calls.get(name, 0) + 1

    def trigger(self, node: int, frame: int, t_send: float, t_recv: float) -> None:
        self._count("trigger")

    def render(self, t: float, gen: Any) -> None:
        self._count("render")

    def close(self) -> None:
        self._count("close")


def test_a_tap_sees_every_render_tick_on_both_cores() -> None:
    """The base Tap records nothing; an attached one is called by either core."""
    for compiled in (False, True):
        run = _run(compiled=compiled)
        tap = _Counting()
        run.record(tap)
        out = run.run()
        assert "close" not in tap.calls  # closing is the caller's (cohort.execute)
        # every render tick of the run (25 Hz for 1 s), the warm-up's included
        assert tap.calls["render"] == 25
        assert len(out["timeseries"]["t"]) == 20  # the collector keeps those after 0.2 s
        issued = run.latest_trigger + 1
        if compiled:  # the compiled core records each trigger's issue
            assert tap.calls["trigger"] == issued
        else:  # one delivery per node (3) of every trigger, the last maybe still in flight
            assert tap.calls["trigger"] % 3 == 0
            assert issued - 1 <= tap.calls["trigger"] // 3 <= issued
