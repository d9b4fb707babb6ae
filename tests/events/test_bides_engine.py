"""BiDES's engine-level parts: adaptive trigger rate, time-warp rollback, lag exclusion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import tiny

from sigma_des.agents.pointmass import PointMass
from sigma_des.events.cohort import make_run
from sigma_des.events.engine import MethodRun
from sigma_des.factory import make_behaviour, make_dynamics


def _run(sc, method: str = "bides") -> MethodRun:  # type: ignore[no-untyped-def]
    """The run on the cohort engine when it supports ``sc`` (it is exact), else per message."""
    run, _why = make_run(replace(sc, engine="cohort").run_spec(), method, make_dynamics(sc),
                         make_behaviour(sc))
    return run


def _expected_rates(lags: np.ndarray, sc) -> list[float]:  # type: ignore[no-untyped-def]
    """Independent re-statement of the adaptation rule, tick by tick."""
    b = sc.bides
    f, hi, lo, out = sc.f_trig, 0, 0, []
    for lag in lags:
        if lag > b.lag_high:
            hi, lo = hi + 1, 0
            if hi >= b.hold_down and f > b.f_trig_min:
                f, hi = max(b.f_trig_min, f * b.rate_down), 0
        elif lag < b.lag_low:
            lo, hi = lo + 1, 0
            if lo >= b.hold_up and f < sc.f_trig:
                f, lo = min(sc.f_trig, f * b.rate_up), 0
        else:
            hi = lo = 0
        out.append(f)
    return out


def test_adaptation_lowers_and_restores_f_trig() -> None:
    degrade = [{"kind": "degrade", "host": h, "start": 0.5, "end": 1.5, "extra_delay": 0.15}
               for h in (0, 1)]
    sc = tiny(**{"duration": 5.0, "warmup": 0.0, "faults": degrade,
                 "bides.rate_down": 0.5, "bides.rate_up": 2.0, "bides.f_trig_min": 25.0,
                 "bides.hold_down": 3, "bides.hold_up": 10, "bides.lag_high": 10,
                 "bides.lag_low": 3, "bides.lag_exclusion": False})
    out = _run(sc).run()
    ts = out["timeseries"]
    f = ts["f_trig"]
    assert f.min() == 25.0  # 100 → 50 → 25, floored at f_trig_min
    assert f[0] == 100.0 and f[-1] == 100.0  # restored after the window
    ok = ts["aligned_frame"] >= 0
    lags = (ts["latest_trigger"] - ts["aligned_frame"])[ok]
    assert f[ok].tolist() == _expected_rates(lags, sc)
    # the rate drops only while the lag is over the threshold
    first_drop = int(np.argmax(f < 100.0))
    assert ts["t"][first_drop] > 0.5
    assert out["metrics"]["f_trig_min_hz"] == 25.0


def test_adaptation_off_keeps_rate() -> None:
    degrade = [{"kind": "degrade", "host": h, "start": 0.5, "end": 1.5, "extra_delay": 0.15}
               for h in (0, 1)]
    sc = tiny(**{"duration": 3.0, "faults": degrade, "bides.adaptation": False})
    out = _run(sc).run()
    assert set(out["timeseries"]["f_trig"].tolist()) == {100.0}


def test_rollback_resimulates_exactly_the_expected_frames() -> None:
    # no behaviour runs, so the hand-delivered command is the node's newest
    sc = tiny(**{"bides.theta_warp": 5})
    # pokes its internals
    run = MethodRun(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    run.start()
    run.kernel.run(0.5)
    i = 0
    current = run.nodes.target[i] if run.nodes.busy[i] else run.nodes.frame[i]
    c = current - 20
    before = run.state.copy()
    H = sc.history_frames
    prev = run.truth.ckpt[(c - 1) % H, i].copy()
    row = np.array([3.0, -4.0, 0.5])
    run.nodes.on_command(i, c, row)
    assert run.truth.rollbacks == 1
    assert run.truth.resim_steps == current - c + 1 == 21
    # the truth of node 0 is re-simulated from its checkpoint with the new command
    dyn = PointMass()
    s = prev[None, :]
    for f in range(c, run.latest_trigger + 1):
        s = dyn.step(s, row[None, :], float(run.truth.frame_dt[f % H]), f, np.array([i]))
        assert np.array_equal(run.truth.ckpt[f % H, i], s[0])
    assert np.array_equal(run.state[i], s[0])
    assert np.array_equal(run.state[1:], before[1:])  # nobody else moved
    # the re-simulation costs the node 21 step times before its next frame
    assert run.nodes.busy[i]


def test_no_rollback_within_theta_warp() -> None:
    sc = tiny(**{"bides.theta_warp": 5})
    # pokes its internals
    run = MethodRun(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    run.start()
    run.kernel.run(0.5)
    current = run.nodes.busy[0] and run.nodes.target[0] or run.nodes.frame[0]
    run.nodes.on_command(0, current - 5, np.array([1.0, 0.0, 0.0]))
    assert run.truth.rollbacks == 0


@pytest.mark.parametrize(("theta", "expect"), [(1000, False), (2, True)])
def test_rollbacks_happen_iff_commands_lag_more_than_theta(theta: int, expect: bool) -> None:
    sc = tiny(**{"commands.enabled": True, "commands.every": 1, "bides.theta_warp": theta,
                 "net.server_link.latency": 0.02})
    m = _run(sc).run()["metrics"]
    assert (m["rollbacks"] > 0) is expect
    if expect:
        # server link 20 ms each way: a command stamped with the aligned frame reaches a
        # node ≥ 4 frames later, so every rollback re-simulates > theta + 1 steps
        assert m["resim_steps"] >= m["rollbacks"] * (theta + 2)


def test_lag_exclusion_keeps_the_swarm_moving_past_a_straggler() -> None:
    slow = [{"kind": "slow", "node": 2, "start": 0.3, "factor": 8.0}]
    sc = tiny(**{"compute.step_time": 0.004, "faults": slow, "duration": 2.0,
                 "bides.adaptation": False, "bides.theta_lag": 5})
    on = _run(sc).run()["metrics"]
    sc_off = tiny(**{"compute.step_time": 0.004, "faults": slow, "duration": 2.0,
                     "bides.adaptation": False, "bides.lag_exclusion": False})
    off = _run(sc_off).run()["metrics"]
    # node 2 needs 32 ms per frame but catches up several frames per job; excluded,
    # it no longer holds the others' AoI up
    assert on["extrapolated_frac"] > 0
    assert off["extrapolated_frac"] == 0
    assert on["aoi_p50"] < off["aoi_p50"]
