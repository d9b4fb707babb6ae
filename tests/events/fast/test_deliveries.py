"""The compiled core's deliveries: BiDES states stored in the aligner's ring inside the
loop, other methods' and a recording tap's states buffered, latencies handed over when
their buffer fills and at the end — with results identical to the per-message engine."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.api import run_method
from sigma_des.events.align.bides import BidesAligner
from sigma_des.events.align.ring import RingBuffers
from sigma_des.events.cohort import make_run
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import deliveries
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.deliveries import records_states
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.tap import Tap
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny


class _States(Tap):
    """A tap that keeps every state delivery row: (t, node, frame, gen, obs...)."""

    def __init__(self) -> None:
        self.rows: list[list[float]] = []

    def states(self, t_recv: Any, nodes: Any, frames: Any, gens: Any, obs: Any) -> None:
        for j in range(len(nodes)):
            self.rows.append([float(t_recv[j]), float(nodes[j]), float(frames[j]),
                              float(gens[j]), *np.asarray(obs[j]).tolist()])


class _Triggers(Tap):
    """A tap that records triggers only (it takes no states)."""

    def trigger(self, node: int, frame: int, t_send: float, t_recv: float) -> None:
        pass


def _run(engine: str, method: str = "bides", tap: Tap | None = None,
         **over: Any) -> tuple[MethodRun, dict[str, Any]]:
    sc = replace(tiny(**over), engine=engine)
    run, why = make_run(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc))
    assert why == ""
    if tap is not None:
        run.record(tap)
    return run, run.run()


def _ring(run: MethodRun) -> RingBuffers:
    al = run.aligner
    assert isinstance(al, BidesAligner)
    return al.ring


def test_records_states_is_whether_the_tap_overrides_states() -> None:
    assert not records_states(Tap())
    assert not records_states(_Triggers())
    assert records_states(_States())


def test_bides_states_go_into_the_ring_in_the_loop(monkeypatch: pytest.MonkeyPatch) -> None:
    """Tiny scenario (3 nodes, 100 Hz, 1 s, no loss): frames 0..99 all arrive before the
    end (5 ms a round trip), so each node's ring of 30 holds frames 70..99, frame f in
    slot f % 30; the loop stored them (on_states is never called, nothing is buffered)."""
    ev_run, ev = _run("events")

    def boom(self: BidesAligner, batch: Any) -> None:
        raise AssertionError("on_states called: the loop should store the states itself")

    monkeypatch.setattr(BidesAligner, "on_states", boom)
    co_run, co = _run("cohort")
    core = co_run.core
    assert isinstance(core, CompiledCore)
    ip = core.S[L.IPARAMS]
    assert (ip[CO.Q_RING], ip[CO.Q_OUT]) == (1, 0)
    assert core.S[L.INTS][CO.I_OUT] == 0  # nothing buffered for Python
    ring, ref = _ring(co_run), _ring(ev_run)
    # the core wrote into the aligner's own arrays, shared to the end (growth, close)
    for name, a in (("ring_frame", ring.frame), ("ring_gen", ring.gen_time),
                    ("ring_obs", ring.obs), ("ring_latest", ring.latest)):
        assert core.array(name) is a, name
    assert ring.latest.tolist() == [99, 99, 99]
    hand = [90 + s if s < 10 else 60 + s for s in range(30)]
    assert ring.frame.tolist() == [hand] * 3
    # the per-message engine's ring, bit for bit, and the whole result
    np.testing.assert_array_equal(ring.frame, ref.frame)
    np.testing.assert_array_equal(ring.gen_time, ref.gen_time)
    np.testing.assert_array_equal(ring.obs, ref.obs)
    assert _same(co["metrics"], ev["metrics"])


@pytest.mark.parametrize("method", ["bides", "hlc"])
def test_a_recording_tap_gets_every_state_in_arrival_order(method: str) -> None:
    """With a tap that takes states the loop buffers them too (BiDES: besides its ring),
    and the tap sees the per-message engine's deliveries, row by row."""
    ev_tap, co_tap = _States(), _States()
    _ev_run, ev = _run("events", method, ev_tap)
    co_run, co = _run("cohort", method, co_tap)
    assert co_run.core.S[L.IPARAMS][CO.Q_OUT] == 1  # type: ignore[attr-defined]
    assert len(co_tap.rows) == len(ev_tap.rows) > 3 * 90
    assert co_tap.rows == ev_tap.rows
    assert _same(co["metrics"], ev["metrics"])


def test_latencies_flushed_when_their_buffer_fills(monkeypatch: pytest.MonkeyPatch) -> None:
    """Latency buffers of one delivery per node: the loop asks Python to flush them many
    times, and the collector's series are the per-message engine's, in order."""
    monkeypatch.setattr(deliveries, "LAT_FRAMES", 1)
    jitter = {"net.host_link.latency": {"dist": "lognormal", "mean": 0.001, "std": 0.0005}}
    ev_run, ev = _run("events", **jitter)
    co_run, co = _run("cohort", **jitter)
    core = co_run.core
    assert isinstance(core, CompiledCore)
    assert core.exit_counts()["NEED_FLUSH"] > 50
    for kind in ("trigger", "state"):
        a, b = co_run.collector.latencies(kind), ev_run.collector.latencies(kind)
        assert a.size == b.size > 3 * 70 and a.tolist() == b.tolist(), kind
    assert _same(co["metrics"], ev["metrics"])


@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_every_method_identical_with_loss(method: str) -> None:
    """States lost on the way (datagram, 5 % per host link): cohort == events."""
    sc = tiny(**{"net.host_link.loss.p": 0.05, "net.transport": "datagram"})
    ev = run_method(replace(sc, engine="events"), method)
    co = run_method(replace(sc, engine="cohort"), method)
    assert co["engine"]["used"] == "cohort", co["engine"]
    assert _same(co["metrics"], ev["metrics"])


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Equal metric dicts, NaN equal to NaN."""
    return a.keys() == b.keys() and all(
        x == y or (isinstance(x, float) and isinstance(y, float) and x != x and y != y)
        for x, y in ((a[k], b[k]) for k in a))
