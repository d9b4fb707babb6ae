"""The cohort engine reproduces the per-message engine exactly (docs/concepts/engines.md).

Every test runs one scenario on both engines and compares the whole result:
every metric, per-link throughput, the per-render-tick time series and the
fidelity series, bit for bit. Scenarios the cohort core does not reproduce must
fall back to the per-message engine and say why.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sigma_des.events.fast.driver as driver
from sigma_des import Scenario, load
from sigma_des.api import ideal_run, run_method
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast.support import CohortFallback, unsupported
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def run_both(sc: Scenario, method: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run ``method`` on both engines; assert identical results; return both."""
    ideal = ideal_run(sc)[1] if sc.fidelity.enabled else None
    ev = run_method(replace(sc, engine="events"), method, ideal=ideal)
    co = run_method(replace(sc, engine="cohort"), method, ideal=ideal)
    diff = {
        k: (ev["metrics"][k], co["metrics"].get(k))
        for k in ev["metrics"]
        if not _same(ev["metrics"][k], co["metrics"].get(k))
    }
    assert not diff, f"{method}: metrics differ: {diff}"
    assert set(ev["metrics"]) == set(co["metrics"])
    assert ev["links_mbps"] == co["links_mbps"]
    for key, series in ev["timeseries"].items():
        np.testing.assert_array_equal(series, co["timeseries"][key], err_msg=key)
    if "fidelity" in ev:
        np.testing.assert_array_equal(
            ev["fidelity"]["formation_err"], co["fidelity"]["formation_err"]
        )
    assert ev["engine"]["used"] == "events"
    return ev, co


@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_tiny_hand_scenario_identical(method: str) -> None:
    _ev, co = run_both(tiny(), method)
    assert co["engine"] == {"requested": "cohort", "used": "cohort", "fallback": ""}


def test_200_nodes_with_loss_adaptation_and_rollbacks() -> None:
    """A fixed larger case: 200 quadrotors, 2 % loss (datagram), adaptation, time warp."""
    sc = load(
        None,
        [
            "duration=2.0",
            "warmup=0.5",
            'net.transport="datagram"',
            "net.qos=0",
            "net.host_link.loss.p=0.02",
            "net.server_link.loss.p=0.01",
            'net.host_link.latency={dist="lognormal", mean=0.002, std=0.001}',
            # a slow broker makes BiDES lag, adapt its rate and roll nodes back
            "broker.publish_service=0.00002",
            "broker.delivery_service=0.000015",
            "bides.theta_warp=2",
            "bides.hold_down=1",
        ],
    )
    for method in ("none", "lockstep", "hlc", "bides"):
        ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"
        if method == "lockstep":
            assert ev["metrics"]["rerequests"] > 0  # lost states were asked for again
        if method == "bides":
            m = ev["metrics"]
            # the case really exercises what it claims to
            assert m["rollbacks"] > 0
            assert m["f_trig_min_hz"] < 100.0
            assert m["filled_frac"] > 0.0


def test_crash_slow_drift_and_qos1_stream_identical() -> None:
    sc = tiny(
        nodes=12,
        duration=2.0,
        faults=[
            {"kind": "crash", "node": 2, "start": 0.7},
            {"kind": "slow", "node": 3, "start": 0.3, "end": 1.5, "factor": 6.0},
            {"kind": "slow", "node": 3, "start": 1.0, "end": 1.2, "factor": 2.0},
        ],
        **{
            "clocks.offset_std": 0.003,
            "clocks.drift_ppm_std": 80.0,
            "net.qos": 1,
            "commands.enabled": True,
            "dynamics": "fixedwing",
        },
    )
    for method in ("none", "hlc", "bides"):
        run_both(sc, method)


def test_growth_and_flush_paths_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    """With no spare capacity the core must grow its tables and flush mid-run."""
    monkeypatch.setattr(driver, "SLACK", 0)
    sc = tiny(
        nodes=6,
        **{
            "broker.publish_service": 0.001,
            "broker.delivery_service": 0.0008,
            "commands.enabled": True,
        },
    )
    for method in ("none", "bides"):
        run_both(sc, method)
    run = MethodRun(replace(sc, engine="cohort").run_spec(), "none", make_dynamics(sc),
                    make_behaviour(sc), compiled=True)
    assert isinstance(run.core, driver.CompiledCore)
    cap0 = run.core.array("heap_t").size
    caps: list[int] = []
    run.run(lambda t: caps.append(run.core.array("heap_t").size))  # before it is closed
    assert caps[-1] > cap0  # the event table grew


@pytest.mark.parametrize(
    ("over", "method", "why"),
    [
        (
            {"clocks.ntp_period": 1e-7, "clocks.ntp_residual_std": 1e-4},
            "hlc",
            "NTP-corrected clocks: residual table too large",
        ),
    ],
)
def test_unsupported_features_fall_back_and_say_why(
    over: dict[str, Any], method: str, why: str
) -> None:
    sc = tiny(**over)
    assert why in (unsupported(sc.run_spec(), method) or "")
    _ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "events"
    assert why in co["engine"]["fallback"]
    with pytest.raises(CohortFallback, match=why):
        MethodRun(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc), compiled=True)


def test_lockstep_eviction_rejoin_and_republish_identical() -> None:
    """Lock-Step's barrier exits: re-requests, republished states, eviction, rejoin."""
    sc = tiny(
        nodes=8,
        duration=2.0,
        faults=[
            {"kind": "crash", "node": 1, "start": 0.5},
            {"kind": "slow", "node": 4, "start": 0.3, "end": 0.6, "factor": 30.0},
        ],
        **{
            "net.transport": "datagram",
            "net.host_link.loss": {"p": 0.1},
            "lockstep.retry_timeout": 0.02,
            "lockstep.eviction_timeout": 0.08,
            "commands.enabled": True,
        },
    )
    ev, co = run_both(sc, "lockstep")
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    assert m["evicted"] >= 2 and m["rejoined"] >= 1 and m["rerequests"] > 0


def test_lockstep_stalled_by_a_crash_counts_duplicate_rerequests() -> None:
    """A crashed node without eviction stalls Lock-Step; past 63 retries the re-request
    index repeats (frame * 64 + min(retry, 63)) and repeats count as duplicates."""
    sc = tiny(
        duration=1.0,
        faults=[{"kind": "crash", "node": 1, "start": 0.2}],
        **{"lockstep.retry_timeout": 0.005},
    )
    ev, co = run_both(sc, "lockstep")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["duplicates"] > 0


def test_draw_older_than_history_falls_back_mid_run() -> None:
    """A node so slow it catches up more than ``history_frames`` frames at once."""
    sc = tiny(
        history_frames=16,
        faults=[{"kind": "slow", "node": 0, "start": 0.1, "end": 0.6, "factor": 40.0}],
        **{"compute.step_time": {"dist": "uniform", "low": 0.001, "high": 0.003}},
    )
    ev, co = run_both(sc, "none")
    assert co["engine"]["used"] == "events"
    assert "history_frames" in co["engine"]["fallback"]
    assert ev["metrics"]["history_misses"] > 0


_LAT = st.sampled_from(
    [
        0.0005,
        {"dist": "uniform", "low": 0.0002, "high": 0.004},
        {"dist": "normal", "mean": 0.003, "std": 0.002},
        {"dist": "exponential", "mean": 0.001},
    ]
)


_LOSS = st.sampled_from(
    [
        {"p": 0.0},
        {"p": 0.05},
        {"p": 0.3},
        {"model": "gilbert_elliott", "p_gb": 0.05, "p_bg": 0.4, "loss_good": 0.01,
         "loss_bad": 0.7, "slot": 0.004},
    ]
)


@st.composite
def scenarios(draw: st.DrawFn) -> tuple[Scenario, str]:
    """Small random scenarios mixing every option the cohort core handles."""
    n = draw(st.integers(2, 20))
    transport = draw(st.sampled_from(["stream", "datagram"]))
    over: dict[str, Any] = {
        "seed": draw(st.integers(0, 2**31)),
        "nodes": n,
        "hosts": draw(st.integers(1, min(4, n))),
        "cores_per_host": draw(st.integers(1, 4)),
        "f_trig": draw(st.sampled_from([50.0, 100.0, 200.0])),
        "f_align": draw(st.sampled_from([20.0, 30.0, 60.0])),
        "duration": 1.0,
        "warmup": draw(st.sampled_from([0.0, 0.2])),
        "dynamics": draw(st.sampled_from(["pointmass", "pointmass", "fixedwing", "quadrotor"])),
        "net.transport": transport,
        "broker.publish_service": draw(st.sampled_from([0.0, 0.00005, {"dist": "exponential",
                                                                       "mean": 0.0001}])),
        "broker.delivery_service": draw(st.sampled_from([0.0, 0.00003])),
        "compute.step_time": draw(st.sampled_from([0.002, {"dist": "lognormal", "mean": 0.002,
                                                           "std": 0.001}])),
        "commands.enabled": draw(st.booleans()),
        "commands.every": draw(st.integers(1, 3)),
        "bides.adaptation": draw(st.booleans()),
        "bides.hold_down": draw(st.integers(1, 3)),
        "bides.time_warp": draw(st.booleans()),
        "bides.theta_warp": draw(st.integers(0, 4)),
        "bides.lag_exclusion": draw(st.booleans()),
        "bides.hole_fill": draw(st.booleans()),
        "clocks.offset_std": draw(st.sampled_from([0.0, 0.002])),
        "clocks.drift_ppm_std": draw(st.sampled_from([0.0, 100.0])),
    }
    if draw(st.booleans()):  # NTP-corrected clocks
        over["clocks.ntp_period"] = draw(st.sampled_from([0.05, 0.3]))
        over["clocks.ntp_residual_std"] = draw(st.sampled_from([0.0, 1e-4]))
    faults = []
    over["net.qos"] = draw(st.sampled_from([0, 1]))
    if transport == "datagram" or draw(st.booleans()):  # a stream: hold-back, RTO retries
        over["net.host_link.latency"] = draw(_LAT)
        over["net.server_link.latency"] = draw(_LAT)
        over["net.host_link.loss"] = draw(_LOSS)
        over["net.server_link.loss"] = draw(_LOSS)
        # QoS 1 over datagram: resends, late and lost PUBACKs, redeliveries, give-ups
        over["net.qos1_timeout"] = draw(st.sampled_from([0.002, 0.004, 0.05]))
        over["net.rto"] = draw(st.sampled_from([0.002, 0.01]))
        over["net.max_retries"] = draw(st.sampled_from([0, 1, 3]))
        if draw(st.booleans()):
            faults.append({"kind": "degrade", "host": draw(st.integers(0, over["hosts"] - 1)),
                           "start": draw(st.sampled_from([0.0, 0.3])), "end": 0.7,
                           "extra_delay": draw(st.sampled_from([0.0, 0.003])),
                           "extra_loss": draw(st.sampled_from([0.0, 0.3]))})
        if draw(st.booleans()):
            faults.append({"kind": "drop", "node": draw(st.integers(0, n - 1)),
                           "frame": draw(st.integers(0, 40)),
                           "message": draw(st.sampled_from(["trigger", "state", "command"]))})
    if draw(st.booleans()):
        faults.append({"kind": "crash", "node": draw(st.integers(0, n - 1)),
                       "start": draw(st.sampled_from([0.0, 0.3]))})
    if draw(st.booleans()):
        faults.append({"kind": "slow", "node": draw(st.integers(0, n - 1)), "start": 0.2,
                       "end": 0.7, "factor": draw(st.sampled_from([2.0, 10.0]))})
    if faults:
        over["faults"] = faults
    if draw(st.booleans()):
        over["lockstep.eviction_timeout"] = draw(st.sampled_from([0.05, 0.2]))
    return tiny(**over), draw(st.sampled_from(["none", "lockstep", "hlc", "bides"]))


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(scenarios())
def test_random_scenarios_identical(case: tuple[Scenario, str]) -> None:
    sc, method = case
    _ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"


_DATAGRAM = {"net.transport": "datagram", "net.qos": 0}


@pytest.mark.parametrize(
    ("base", "feature", "method"),
    [
        pytest.param(
            _DATAGRAM,
            {"net.server_link.loss": {"model": "gilbert_elliott", "p_gb": 0.1, "p_bg": 0.5},
             "net.host_link.loss": {"model": "gilbert_elliott", "p_gb": 0.05, "p_bg": 0.3,
                                    "loss_good": 0.01, "loss_bad": 0.6, "slot": 0.002}},
            "bides",
            id="gilbert-elliott",
        ),
        pytest.param(
            {**_DATAGRAM, "net.host_link.loss": {"p": 0.05}},
            {"faults": [
                {"kind": "degrade", "host": 0, "start": 0.2, "end": 0.6, "extra_delay": 0.004,
                 "extra_loss": 0.2},
                {"kind": "degrade", "host": 0, "start": 0.4, "end": 0.8, "extra_delay": 0.001,
                 "extra_loss": 0.1},
                {"kind": "degrade", "host": 1, "start": 0.1, "end": 0.5, "extra_delay": 0.003},
            ]},
            "lockstep",
            id="degrade",
        ),
        pytest.param(
            {**_DATAGRAM, "commands.enabled": True},
            {"faults": [
                {"kind": "drop", "node": 1, "frame": 20, "message": "state"},
                {"kind": "drop", "node": 0, "frame": 10, "message": "trigger"},
                {"kind": "drop", "node": 2, "frame": 3, "message": "command"},
            ]},
            "lockstep",
            id="drop",
        ),
        pytest.param(
            {"clocks.offset_std": 0.002, "clocks.drift_ppm_std": 100.0},
            {"clocks.ntp_period": 0.1, "clocks.ntp_residual_std": 1e-4},
            "hlc",
            id="ntp",
        ),
    ],
)
def test_link_features_run_compiled_and_identical(
    base: dict[str, Any], feature: dict[str, Any], method: str
) -> None:
    """Gilbert–Elliott loss, degrade and drop faults and NTP clocks run on the cohort
    core, bit-identical to the per-message engine, and each changes the result."""
    ev, co = run_both(tiny(**base, **feature), method)
    assert co["engine"] == {"requested": "cohort", "used": "cohort", "fallback": ""}
    without = run_method(replace(tiny(**base), engine="events"), method)["metrics"]
    assert any(not _same(v, without[k]) for k, v in ev["metrics"].items())


def test_send_beyond_the_link_tables_falls_back_mid_run() -> None:
    """A broker backlog of seconds: deliveries leave past the Gilbert–Elliott table
    (the run's end + 1 s), so the cohort run is redone per message."""
    sc = tiny(**{**_DATAGRAM, "broker.publish_service": 0.02,
                 "net.host_link.loss": {"model": "gilbert_elliott", "p_gb": 0.1, "p_bg": 0.5}})
    _ev, co = run_both(sc, "none")
    assert co["engine"]["used"] == "events"
    assert "beyond the link and clock tables" in co["engine"]["fallback"]
