"""Hand-computed tiny scenarios for the ``rpc`` method (AirSim-style synchronous calls).

Scenario: tests/conftest.py TINY (MQTT broker with zero service time: a plain relay;
stream transport, constant latencies, compute 2 ms), with constant call time K and
render time R + V per vehicle.

Sequential calls (``in_flight = 1``): one call = request (server up WT*tau + LS,
host down WT*tau + LH) + compute C + response (host up WS*tau + LH, server down
WS*tau + LS) + the game thread's K; nothing queues. A frame = 3 calls + render,
so triggers are (3 D + R + 3V) apart when that exceeds 1/f_trig.

Parallel calls (``in_flight = 0``): the 3 requests leave the server back to back
(WT*tau apart), node 0's response reaches the server first, at
T + 2WT*tau + LS + LH + C + 2WS*tau + LH + LS, then the thread handles the three
responses back to back (3K: they arrive WS*tau apart, < K), then renders.
"""

from __future__ import annotations

import pytest
from conftest import tiny

from sigma_des import compare
from sigma_des.events.engine import MethodRun
from sigma_des.factory import make_behaviour, make_dynamics

TAU = 8.0 / 100e6
LH, LS, C = 0.001, 0.0005, 0.002
WT, WS = 98, 109
K, R, V = 0.0003, 0.005, 0.0001
RPC = {"rpc.call_time": K, "rpc.render_time": R, "rpc.render_per_vehicle": V}


def _run(**over: object) -> MethodRun:
    sc = tiny(methods=["rpc"], **{**RPC, **over})
    run = MethodRun(sc, "rpc", make_dynamics(sc), make_behaviour(sc))
    run.run()
    return run


def _periods(run: MethodRun) -> list[float]:
    H = run.sc.history_frames
    return [run.trig_time[(k + 1) % H] - run.trig_time[k % H] for k in range(5, 30)]


def test_sequential_calls_frame_time_exact() -> None:
    run = _run(**{"rpc.in_flight": 1})
    call = 2 * WT * TAU + LS + LH + C + 2 * WS * TAU + LH + LS + K
    frame = 3 * call + R + 3 * V
    assert frame > 0.010
    for d in _periods(run):
        assert d == pytest.approx(frame, abs=1e-12)
    # 3 calls per finished frame, and 1..3 in the frame the run's end cuts
    calls = run.aligner.calls  # type: ignore[attr-defined]
    assert 3 * run.latest_trigger + 1 <= calls <= 3 * (run.latest_trigger + 1)


def test_parallel_calls_frame_time_exact() -> None:
    run = _run(**{"rpc.in_flight": 0})
    first = 2 * WT * TAU + LS + LH + C + 2 * WS * TAU + LH + LS
    frame = first + 3 * K + R + 3 * V
    for d in _periods(run):
        assert d == pytest.approx(frame, abs=1e-12)


def test_fast_frames_keep_the_nominal_rate() -> None:
    # render 0 and tiny call times: one frame < 10 ms, so triggers stay 10 ms apart
    run = _run(**{"rpc.in_flight": 0, "rpc.render_time": 0.0, "rpc.render_per_vehicle": 0.0})
    for d in _periods(run):
        assert d == pytest.approx(0.010, abs=1e-12)


@pytest.mark.parametrize("engine", ["events", "cohort"])
def test_rpc_shows_the_rendered_frame(engine: str) -> None:
    res = compare(tiny(engine=engine, methods=["rpc"], **RPC, **{"rpc.in_flight": 1}),
                  progress=False)
    m = res.methods["rpc"]
    call = 2 * WT * TAU + LS + LH + C + 2 * WS * TAU + LH + LS + K
    frame = 3 * call + R + 3 * V
    assert m["trigger_rate_hz"] == pytest.approx(1 / frame, abs=1 / 0.8)  # ±1 trigger
    assert m["spread_max"] == 0.0  # one frame shown for all vehicles
    assert res.engines["rpc"]["used"] == "events"
    if engine == "cohort":
        assert "rpc method" in res.engines["rpc"]["fallback"]


def test_rpc_over_dds_is_refused_naming_the_key(capsys: pytest.CaptureFixture[str]) -> None:
    from sigma_des.cli import main

    args = ["compare", "--no-progress", "--methods", "rpc", "--set", "net.middleware=dds",
            "--set", "net.transport=datagram", "--set", "net.qos=0", "--set", "nodes=3",
            "--set", "hosts=1"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "methods" in err and "middleware" in err and "Traceback" not in err
