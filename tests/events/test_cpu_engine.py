"""The CPU stage, per-host clients and bundles in the per-message engine (engine = events).

Scenario of the closed forms: one host whose cores outnumber its nodes, constant
step time and latencies, an instantaneous broker (so it holds no core), QoS 0, no
commands: every node of a frame publishes at the same instant.
"""

from __future__ import annotations

from typing import Any

import pytest
from conftest import tiny

from sigma_des import Scenario, load
from sigma_des.events.cohort import execute
from sigma_des.events.engine import MethodRun
from sigma_des.factory import make_behaviour, make_dynamics

F = 100.0
BATCH = ["dynamics='pointmass'", "engine='events'", "hosts=1", "cores_per_host=64",
         f"f_trig={F}", "duration=1.5", "warmup=0.5", "net.qos=0", "net.transport='stream'",
         "broker.publish_service=0.0", "broker.delivery_service=0.0",
         "compute.step_time=0.0008", "commands.enabled=false", "fidelity.enabled=false",
         "net.host_link.latency=0.0005", "net.server_link.latency=0.0005"]


def _run(sc: Scenario, method: str = "none") -> tuple[MethodRun, dict[str, Any]]:
    run, out, engine = execute(sc.run_spec(), method, lambda: make_dynamics(sc),
                               lambda: make_behaviour(sc))
    assert engine["used"] == "events"
    return run, out


def _shared(m: dict[str, float]) -> dict[str, Any]:
    """The metrics a run without a CPU stage has too (NaN as a comparable token)."""
    return {k: ("nan" if v != v else v) for k, v in m.items() if "cpu" not in k}


@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_zero_demands_are_todays_model_bit_for_bit(method: str) -> None:
    over = {"engine": "events", "broker__publish_service": 4e-6,
            "broker__delivery_service": 3e-6, "commands__enabled": True}
    sc = tiny(**over)
    on = tiny(**over, deployment__preset="colocated", deployment__cores=1)
    base = _run(sc, method)[1]["metrics"]
    got = _run(on, method)[1]["metrics"]
    assert "server_cpu_util" not in base and "server_cpu_util" in got
    assert _shared(got) == _shared(base)  # the broker alone on its core: the same Lindley recursion
    assert got["server_cpu_util"] == 0.0 and got["host_cpu_util_max"] == 0.0


def test_server_queue_waits_exactly_and_the_latency_ends_when_the_thread_takes_it() -> None:
    """N states of a frame reach the server together (spaced by their serialization
    ``ser`` on its link); its one thread serves them one by one, so state ``k`` waits
    ``k·(Ds − ser)`` for the thread. Live stamps a receipt when the process gets to the
    message, so that wait is in the latency: the mean state latency grows by exactly
    ``(N−1)/2·(Ds − ser)``, and the trigger's by exactly the server's publish burst
    ``Ds`` (its thread is idle when the trigger fires; the host's receipt does not
    wait). The server's utilisation is ``(N+1)·f·Ds`` (each frame's N receives and its
    trigger publish)."""
    ds = 1e-4
    for n in (20, 40, 60):
        plain = load(None, [*BATCH, f"nodes={n}"])
        cpu = load(None, [*BATCH, f"nodes={n}", "deployment.preset='colocated'",
                          "deployment.cores=1", f"deployment.server_demand={ds}"])
        run0, out0 = _run(plain)
        _run1, out1 = _run(cpu)
        m0, m1 = out0["metrics"], out1["metrics"]
        ser = run0.net.wire_bytes(plain.payload_bits) * 8 / 1e9
        assert m1["latency_state_mean"] - m0["latency_state_mean"] == pytest.approx(
            (n - 1) / 2 * (ds - ser) * 1e3, rel=1e-6)
        assert m1["latency_trigger_mean"] - m0["latency_trigger_mean"] == pytest.approx(
            ds * 1e3, rel=1e-6)
        assert m1["server_cpu_util"] == pytest.approx((n + 1) * F * ds, rel=1e-3)
        assert m1["server_cpu_max_wait_ms"] == pytest.approx((n - 1) * (ds - ser) * 1e3,
                                                             rel=1e-6)


def test_wake_up_charged_once_per_idle_period_of_the_server() -> None:
    """Each frame the server's thread wakes twice: for the trigger's publish (idle since
    the last batch) and for the first of the N states (the batch arrives ~1.3 ms later,
    when the trigger's burst is long over); the other N − 1 states queue behind the
    first and pay the demand only. So the server's utilisation is exactly
    ``f·((N + 1)·Ds + 2·Dw)``, the longest wait grows by the first state's wake, and so
    does the wait, hence the latency, of each of the N − 1 states behind it."""
    ds, dw, n = 1e-4, 3e-4, 20
    base = [*BATCH, f"nodes={n}", "deployment.preset='colocated'", "deployment.cores=1",
            f"deployment.server_demand={ds}"]
    _r, plain = _run(load(None, base))
    _r, woke = _run(load(None, [*base, f"deployment.server_wake={dw}"]))
    m0, m1 = plain["metrics"], woke["metrics"]
    assert m1["server_cpu_util"] == pytest.approx(F * ((n + 1) * ds + 2 * dw), rel=1e-3)
    assert m1["server_cpu_max_wait_ms"] - m0["server_cpu_max_wait_ms"] == pytest.approx(
        dw * 1e3, rel=1e-6)
    assert m1["latency_state_mean"] - m0["latency_state_mean"] == pytest.approx(
        (n - 1) / n * dw * 1e3, rel=1e-6)


def test_overloaded_server_falls_behind_with_n() -> None:
    """Server demand 0.4 ms: load (N+1)·f·Ds = 0.84, 1.24, 1.64 at N = 20, 30, 40.
    Below 1 the server keeps up (its longest wait is below a frame's batch plus a
    trigger period); beyond 1 its backlog grows for the whole run: it is busy all the
    time, its triggers leave ever later (stamped when its thread gets to them, as live
    stamps them, so their latency stays one burst and a trip) and the age of what it
    shows grows."""
    ds = 4e-4
    aoi = []
    for n in (20, 30, 40):
        sc = load(None, [*BATCH, f"nodes={n}", "deployment.preset='colocated'",
                         "deployment.cores=1", f"deployment.server_demand={ds}"])
        m = _run(sc)[1]["metrics"]
        aoi.append(m["aoi_mean"])
        rho = (n + 1) * F * ds
        if rho < 1:
            assert m["server_cpu_util"] == pytest.approx(rho, rel=1e-3)
            assert m["server_cpu_max_wait_ms"] < (n + 1) * ds * 1e3 + 1e3 / F
        else:
            assert m["server_cpu_util"] > 0.99
            assert m["latency_trigger_mean"] < ds * 1e3 + 2.0
            assert m["server_cpu_max_wait_ms"] > 100.0
    assert aoi[0] < aoi[1] < aoi[2]


def test_background_doubles_the_server_queue() -> None:
    """Background 1 of 2 cores: every demand takes twice as long, so the batch wait
    (Ds scaled) is that of twice the demand."""
    n, ds = 20, 1e-4
    a = load(None, [*BATCH, f"nodes={n}", "deployment.preset='dedicated'",
                    "deployment.cores=2", "deployment.background=1.0",
                    f"deployment.server_demand={ds}"])
    b = load(None, [*BATCH, f"nodes={n}", "deployment.preset='dedicated'",
                    "deployment.cores=1", f"deployment.server_demand={2 * ds}"])
    assert _shared(_run(a)[1]["metrics"]) == _shared(_run(b)[1]["metrics"])


def test_host_clients_cut_the_brokers_trigger_fan_out_to_h_deliveries() -> None:
    n, h, d = 6, 2, 3e-5
    over = [*BATCH, f"nodes={n}", f"hosts={h}", "broker.delivery_service=3e-5"]
    node_run, node = _run(load(None, over))
    host_run, host = _run(load(None, [*over, "deployment.clients='host'"]))
    # every node still gets every trigger: the same deliveries at the application
    assert host["metrics"]["deliveries_per_s"] == node["metrics"]["deliveries_per_s"]
    # the broker spends (N - H) fewer delivery parts per trigger, nothing else changes
    saved = node_run.net.broker.work - host_run.net.broker.work
    triggers = node["metrics"]["trigger_rate_hz"] * (1.5 - 0.5)
    assert saved == pytest.approx(triggers * (n - h) * d, rel=1e-6)


def test_bundle_one_state_publish_per_host_per_completion_instant() -> None:
    n, h = 6, 2
    over = [*BATCH, f"nodes={n}", f"hosts={h}", "net.transport='datagram'",
            "deployment.clients='host'"]
    run1, out1 = _run(load(None, over))
    run2, out2 = _run(load(None, [*over, "deployment.bundle=true"]))
    up1 = {ld.name: ld.packets for ld in run1.net.links()}
    up2 = {ld.name: ld.packets for ld in run2.net.links()}
    frames = round(out1["metrics"]["trigger_rate_hz"] * 1.0)
    # QoS 0: the uplinks carry only states; 3 nodes a host, one completion instant a frame
    assert up1["host0.up"] == up1["host1.up"] == 3 * frames
    assert up2["host0.up"] == up2["host1.up"] == frames
    # the server still gets every node's state of every frame
    assert out2["metrics"]["deliveries_per_s"] == out1["metrics"]["deliveries_per_s"]
    assert out2["metrics"]["latency_state_mean"] < out1["metrics"]["latency_state_mean"]


def test_server_tick_burst_delays_the_states_behind_it() -> None:
    """An alignment tick's burst on the server's thread: states arriving during it
    wait for the thread; with no tick cost they do not."""
    base = [*BATCH, "nodes=4", "deployment.preset='dedicated'", "deployment.server_demand=1e-5"]
    m0 = _run(load(None, base))[1]["metrics"]
    m1 = _run(load(None, [*base, "deployment.server_tick=0.005"]))[1]["metrics"]
    # the wait is before the process takes the state: in its latency and in the
    # server's longest wait
    assert m1["latency_state_mean"] > m0["latency_state_mean"]
    assert m1["server_cpu_max_wait_ms"] > m0["server_cpu_max_wait_ms"] + 1.0
    assert m1["server_cpu_util"] == pytest.approx(m0["server_cpu_util"] + 60 * 0.005, rel=1e-2)


@pytest.mark.parametrize("over", [
    ["deployment.preset='colocated'", "deployment.host_demand=5e-5",
     "deployment.server_demand=5e-5", "deployment.server_tick=1e-4"],
    ["deployment.preset='dedicated'", "deployment.clients='host'", "deployment.bundle=true",
     "deployment.host_demand=5e-5", "deployment.server_demand=5e-5"],
])
def test_same_seed_same_results(over: list[str]) -> None:
    sc = load(None, ["nodes=12", "hosts=3", "duration=1.0", "engine='events'",
                     "fidelity.enabled=false", "net.transport='datagram'",
                     "net.host_link.loss.p=0.05", *over])
    for method in ("lockstep", "bides"):
        assert _run(sc, method)[1]["metrics"] == _run(sc, method)[1]["metrics"]


def test_bundle_sends_a_ticks_commands_once_per_host() -> None:
    """Commands every 3rd alignment tick (60 Hz): 20 ticks a second. Per node, the server
    sends N commands a tick; bundled, H PUBLISHes a tick (live ``--bundle``). The
    server's uplink, counted in the 1 s metrics window, carries 100 triggers plus those:
    100 + 20 N packets against 100 + 20 H; every node still gets its commands."""
    n, h = 6, 2
    over = [*BATCH, f"nodes={n}", f"hosts={h}", "commands.enabled=true",
            "deployment.clients='host'"]
    run1, out1 = _run(load(None, over))
    run2, out2 = _run(load(None, [*over, "deployment.bundle=true"]))
    up1 = {ld.name: ld.packets for ld in run1.net.links()}["server.up"]
    up2 = {ld.name: ld.packets for ld in run2.net.links()}["server.up"]
    ticks = (up1 - up2) / (n - h)
    assert ticks == 20  # 20 Hz over the 1 s window
    assert up2 == pytest.approx(100 + h * ticks, abs=1)
    assert out2["metrics"]["latency_command_mean"] > 0.0
    assert out2["metrics"]["deliveries_per_s"] == out1["metrics"]["deliveries_per_s"]


@pytest.mark.parametrize("engine", ["events", "cohort"])
def test_a_render_tick_waits_for_the_loop_threads_queue(engine: str) -> None:
    """Alignment ticks at ``j / 100`` each cost the server's loop thread 7 ms
    (``server_tick``, nothing else on it); a render tick due at ``(j + 0.5) / 100`` finds
    that thread busy and runs when it frees, at ``(j + 0.7) / 100`` (live's loop drains
    what it holds before its timers). Mean AoI is then exactly that of render ticks at
    phase 0.7, and 2 ms above phase 0.5's without the tick's CPU."""
    grid = [*BATCH, "nodes=10", "f_align=100", "f_render=100", "align_phase=0.0",
            f"engine='{engine}'"]
    busy = ["deployment.preset='colocated'", "deployment.server_tick=0.007"]

    def aoi(*extra: str) -> float:
        sc = load(None, [*grid, *extra])
        _run, out, used = execute(sc.run_spec(), "none", lambda: make_dynamics(sc),
                                  lambda: make_behaviour(sc))
        assert used["used"] == engine
        return float(out["metrics"]["aoi_mean"])

    late = aoi("render_phase=0.5", *busy)
    assert late == pytest.approx(aoi("render_phase=0.7"), rel=1e-12)
    assert late - aoi("render_phase=0.5") == pytest.approx(2.0, rel=1e-9)
