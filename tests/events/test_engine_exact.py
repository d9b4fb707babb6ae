"""Hand-computed tiny scenarios: every method's AoI, latency, rates and spread exactly.

Scenario (tests/conftest.py TINY): nodes 0,1 on host 0, node 2 on host 1; host
links 1 ms, server link 0.5 ms, 100 Mbps (80 ns per byte); broker instantaneous;
compute 2 ms; QoS 0; triggers at 100 Hz; align and render at 25 Hz; window
[0.2 s, 1.0 s).

Derivation (tau = 80 ns/byte, Wt = 98 B trigger frame, Ws = 109 B state frame):
  trigger k leaves the server at T_k, reaches the broker after Wt·tau + Ls and is
  fanned out at once. Host 0's downlink serializes node 0 then node 1, so trigger
  arrivals are r0 = r2 = T_k + 2·Wt·tau + Ls + Lh and r1 = r0 + Wt·tau.
  States are published at g_i = r_i + c. Host 0's uplink: node 1's state waits for
  node 0's (Ws > Wt). The server downlink serializes node 0, node 2, node 1.
  State latency: node 0: 2Ws·tau + Lh + Ls; node 2: +Ws·tau; node 1:
  4Ws·tau − Wt·tau + Lh + Ls.
  At render tick t (a multiple of 40 ms) the newest delivered frame is T = t − 10 ms,
  so AoI_i = 10 ms − (g_i − T). HLC stamps equal publish times, so node 1's
  frame (published Wt·tau later) is not yet causally stable: it shows one frame
  older (+10 ms) and the snapshot's spread is 1 frame.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import tiny

from sigma_des import compare
from sigma_des.net.wire import frame_bytes, payload_bytes, publish_bytes

TAU = 8.0 / 100e6
LH, LS, C = 0.001, 0.0005, 0.002
WT, WS = 98, 109
MS = 1000.0


def test_wire_sizes_of_the_tiny_scenario() -> None:
    assert frame_bytes(publish_bytes(8, payload_bytes(64), 0)) == WT
    assert frame_bytes(publish_bytes(8, payload_bytes(150), 0)) == WS


@pytest.fixture(scope="module", params=["events", "cohort"])
def results(request):  # type: ignore[no-untyped-def]
    """The tiny scenario on each engine: both must give the hand-computed figures."""
    return compare(tiny(engine=request.param), progress=False)


def _aoi_none() -> np.ndarray:
    a0 = 0.010 - (2 * WT * TAU + LS + LH + C)
    return np.array([a0, a0 - WT * TAU, a0])


@pytest.mark.parametrize("method", ["none", "lockstep", "bides"])
def test_aoi_exact(results, method: str) -> None:  # type: ignore[no-untyped-def]
    a = _aoi_none()
    m = results.methods[method]
    assert m["aoi_mean"] == pytest.approx(a.mean() * MS, abs=1e-9)
    assert m["aoi_std"] == pytest.approx(a.std() * MS, abs=1e-9)
    assert m["aoi_max"] == pytest.approx(a.max() * MS, abs=1e-9)
    # the shown state is refreshed every 40 ms: the sawtooth averages a + 20 ms,
    # and peaks at a + 40 ms
    assert m["aoi_time_avg"] == pytest.approx((a.mean() + 0.020) * MS, abs=1e-9)
    assert m["aoi_peak_mean"] == pytest.approx((a.mean() + 0.040) * MS, abs=1e-9)
    assert m["spread_mean"] == 0.0
    assert m["pos_err_mean"] == pytest.approx(0.0, abs=1e-12)


def test_hlc_holds_back_the_later_publisher(results) -> None:  # type: ignore[no-untyped-def]
    a = _aoi_none()
    a[1] += 0.010
    m = results.methods["hlc"]
    assert m["aoi_mean"] == pytest.approx(a.mean() * MS, abs=1e-9)
    assert m["aoi_max"] == pytest.approx(a.max() * MS, abs=1e-9)
    assert m["spread_mean"] == 1.0
    assert m["spread_max"] == 1.0


@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_latency_and_rates_exact(results, method: str) -> None:  # type: ignore[no-untyped-def]
    m = results.methods[method]
    lat_state = np.array([2 * WS * TAU, 4 * WS * TAU - WT * TAU, 3 * WS * TAU]) + LH + LS
    lat_trig = np.array([2 * WT * TAU, 3 * WT * TAU, 2 * WT * TAU]) + LH + LS
    assert m["latency_state_mean"] == pytest.approx(lat_state.mean() * MS, abs=1e-9)
    assert m["latency_state_p99"] == pytest.approx(
        np.percentile(np.tile(lat_state, 80), 99) * MS, abs=1e-9)
    assert m["latency_trigger_mean"] == pytest.approx(lat_trig.mean() * MS, abs=1e-9)
    assert m["trigger_rate_hz"] == pytest.approx(100.0)
    assert m["snapshot_rate_hz"] == pytest.approx(25.0)
    assert m["stalls"] == 0
    # every packet counted: per frame 1 trigger up + 3 down + 3 states up + 3 down
    bits = (4 * WT + 6 * WS) * 8 * 100
    assert m["throughput_mbps"] == pytest.approx(bits / 1e6, rel=1e-12)


def test_lockstep_lost_state_waits_exactly_one_retry_timeout() -> None:
    from sigma_des.events.engine import MethodRun
    from sigma_des.factory import make_behaviour, make_dynamics

    sc = tiny(**{"net.transport": "datagram", "lockstep.retry_timeout": 0.03,
                 "faults": [{"kind": "drop", "message": "state", "node": 2, "frame": 50}]})
    run = MethodRun(sc, "lockstep", make_dynamics(sc), make_behaviour(sc))
    run.run()
    H = sc.history_frames
    t50 = run.trig_time[50 % H]
    t51 = run.trig_time[51 % H]
    assert t50 == pytest.approx(0.5, abs=1e-12)
    # re-request (server up + host 1 down), node 2 republishes at once (host 1 up +
    # server down; nothing else queued then)
    expected = t50 + 0.03 + (2 * WT * TAU + LS + LH) + (2 * WS * TAU + LH + LS)
    assert t51 == pytest.approx(expected, abs=1e-12)
    assert run.aligner.rerequests == 1  # type: ignore[attr-defined]
    # later frames keep the 10 ms period from the new phase
    assert run.trig_time[52 % H] - t51 == pytest.approx(0.010, abs=1e-12)


def test_lockstep_eviction_unblocks_a_crashed_node() -> None:
    from sigma_des.events.engine import MethodRun
    from sigma_des.factory import make_behaviour, make_dynamics

    sc = tiny(**{"lockstep.eviction_timeout": 0.1,
                 "faults": [{"kind": "crash", "node": 1, "start": 0.3}]})
    run = MethodRun(sc, "lockstep", make_dynamics(sc), make_behaviour(sc))
    out = run.run()
    assert run.aligner.evicted == 1  # type: ignore[attr-defined]
    # without eviction the barrier would stall for good
    sc2 = tiny(**{"faults": [{"kind": "crash", "node": 1, "start": 0.3}]})
    run2 = MethodRun(sc2, "lockstep", make_dynamics(sc2), make_behaviour(sc2))
    out2 = run2.run()
    assert run2.latest_trigger < run.latest_trigger
    assert out2["metrics"]["stalls"] >= 1
    assert out["metrics"]["trigger_rate_hz"] > out2["metrics"]["trigger_rate_hz"]


def test_lockstep_evicted_straggler_rejoins() -> None:
    from sigma_des.events.engine import MethodRun
    from sigma_des.factory import make_behaviour, make_dynamics

    # node 1 is 20x slow for 0.2 s: 40 ms per step > the 25 ms eviction timeout
    sc = tiny(**{"lockstep.eviction_timeout": 0.025,
                 "faults": [{"kind": "slow", "node": 1, "start": 0.3, "end": 0.5,
                             "factor": 20.0}]})
    run = MethodRun(sc, "lockstep", make_dynamics(sc), make_behaviour(sc))
    m = run.run()["metrics"]
    al = run.aligner
    assert al.evicted >= 1  # type: ignore[attr-defined]
    assert al.rejoined >= 1  # type: ignore[attr-defined]
    assert bool(al.live.all())  # type: ignore[attr-defined]
    # after the slow window the barrier runs at the full rate again
    k, H = run.latest_trigger, sc.history_frames
    assert run.trig_time[k % H] - run.trig_time[(k - 1) % H] == pytest.approx(0.010, abs=1e-12)
    assert m["evicted"] == al.evicted  # type: ignore[attr-defined]



def test_f_trig_min_counts_a_rate_set_before_the_window() -> None:
    from sigma_des.events.engine import MethodRun
    from sigma_des.factory import make_behaviour, make_dynamics

    sc = tiny(**{"warmup": 0.5, "bides.adaptation": False})
    run = MethodRun(sc, "bides", make_dynamics(sc), make_behaviour(sc))
    run.start()
    run.kernel.run(0.1)
    run.set_rate(50.0)  # lowered before the metrics window opens, and kept
    run._advance(None)
    assert run.finish()["metrics"]["f_trig_min_hz"] == 50.0
