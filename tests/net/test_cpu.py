"""The CPU stage's discipline (net/cpu.py) against hand-computed bursts."""

from __future__ import annotations

import pytest

from sigma_des.errors import ConfigError
from sigma_des.net.cpu import LOAD_WINDOW, RESERVATIONS, U_CAP, Cpu, Machine, queue_wait
from sigma_des.net.spec import DeploymentSpec


def _colocated(cores: int, background: float = 0.0, hosts: int = 1) -> Cpu:
    return Cpu(DeploymentSpec(preset="colocated", cores=cores, background=background), hosts,
               0.0, 100.0)


def test_one_core_two_processes_same_instant_second_waits_the_first_demand() -> None:
    cpu = _colocated(1)
    a, b = cpu.server, cpu.hosts[0]
    assert a.burst(1.0, 0.25) == 1.25
    # the second burst arrives at the same instant: the one core is held until 1.25
    assert b.burst(1.0, 0.5) == 1.75
    assert b.max_wait == 0.25 and a.max_wait == 0.0
    assert (a.busy, b.busy) == (0.25, 0.5)
    assert (a.bursts, b.bursts) == (1, 1)


def test_two_cores_run_two_processes_at_once_but_one_thread_serially() -> None:
    cpu = _colocated(2)
    a, b = cpu.server, cpu.hosts[0]
    assert a.burst(0.0, 1.0) == 1.0  # core 0
    assert b.burst(0.0, 1.0) == 1.0  # core 1: no wait
    # the same thread: FCFS even though a core frees at 1.0 for both
    assert a.burst(0.0, 0.5) == 1.5
    assert a.max_wait == 1.0 and b.max_wait == 0.0


def test_a_burst_fits_in_a_cores_gap_before_a_later_reservation() -> None:
    """Backfilling, by hand: W's second burst is ready only at 3 (its thread), so core 0
    (free from 1) holds [3, 4) and stays idle in [1, 3); Z, arriving at 0.5, fits there
    and starts at 1, not at 3 (the earliest a core would be free if reservations were
    made end to end)."""
    cpu = _colocated(2)
    x, w, z = cpu.broker, cpu.server, cpu.hosts[0]
    assert x.burst(0.0, 1.0) == 1.0  # core 0: [0, 1)
    assert w.burst(0.0, 3.0) == 3.0  # core 1: [0, 3)
    assert w.burst(0.0, 1.0) == 4.0  # ready at 3: both cores give 3, core 0 (lowest)
    assert z.burst(0.5, 1.0) == 2.0  # core 0's gap [1, 3)
    assert z.max_wait == 0.5
    m = cpu.machines[0]
    assert m.cores == [[(0.0, 1.0), (1.0, 2.0), (3.0, 4.0)], [(0.0, 3.0)]]
    # a burst longer than the gap waits for the first core free long enough
    # (core 0: the gap [2, 3) is too short, then 4; core 1: free at 3)
    assert x.burst(1.5, 1.5) == 4.5
    assert m.cores[1] == [(0.0, 3.0), (3.0, 4.5)]


def test_a_wake_up_is_charged_only_to_a_burst_that_finds_its_thread_idle() -> None:
    """Server wake 0.1, demand 0.25, on two cores: the first burst wakes the thread
    (0.35 long); one arriving while it runs queues and costs its demand only; one
    arriving exactly when the thread is free again is no wake-up either (the thread
    has not waited); one after an idle gap wakes it again."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, server_demand=0.25,
                             server_wake=0.1, host_demand=0.5), 1, 0.0, 100.0)
    s, h = cpu.server, cpu.hosts[0]
    assert s.span(0.0, 0.25) == (0.0, 0.35)
    assert s.span(0.1, 0.25) == (0.35, 0.6)
    assert s.span(0.6, 0.25) == (0.6, 0.85)
    assert s.span(1.0, 0.25) == (1.0, 1.35)
    assert s.busy == pytest.approx(0.35 + 0.25 + 0.25 + 0.35, abs=1e-15)
    assert s.max_wait == pytest.approx(0.25, abs=1e-15)
    assert h.burst(0.0, 0.5) == 0.5  # host_wake 0: its bursts are their demand
    assert cpu.broker.wake == 0.0


def test_reservations_ended_by_an_arrival_are_dropped_and_the_cap_merges() -> None:
    m = Machine("all", 1)
    for k in range(RESERVATIONS + 1):
        m.reserve(0, 2.0 * k, 2.0 * k + 1.0)
    ivs = m.cores[0]
    assert len(ivs) == RESERVATIONS
    assert ivs[0] == (0.0, 3.0) and ivs[1] == (4.0, 5.0)  # the two earliest merged
    assert m.place(10.0, 10.0, 1.0) == (11.0, 0)  # [10, 11) is reserved, [11, 12) free
    assert m.cores[0][0] == (10.0, 11.0)  # those ended by 10 are gone


def test_background_one_of_two_cores_doubles_every_demand_exactly() -> None:
    cpu = _colocated(2, background=1.0)
    for d in (1e-4, 3.7e-5, 0.25):
        p = cpu.hosts[0]
        t = p.free
        assert p.burst(t, d) == t + 2.0 * d
    assert cpu.server.scale == 2.0
    # 3 of 4 cores busy elsewhere: four times as long
    assert _colocated(4, background=3.0).broker.burst(0.0, 0.125) == 0.5


def test_dedicated_machines_do_not_share_cores() -> None:
    cpu = Cpu(DeploymentSpec(preset="dedicated", cores=1), 2, 0.0, 100.0)
    ends = [p.burst(0.0, 1.0) for p in cpu.processes]
    assert ends == [1.0] * 4
    assert [m.name for m in cpu.machines] == ["broker", "server", "host0", "host1"]
    rep = cpu.report()
    assert [p.name for p in rep.processes] == ["broker", "server", "host0", "host1"]
    assert [p.machine for p in rep.processes] == ["broker", "server", "host0", "host1"]


def test_counters_only_inside_the_metrics_window() -> None:
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=1), 1, 1.0, 2.0)
    p = cpu.server
    p.burst(0.5, 1.0)  # arrives before the window, runs [0.5, 1.5): 0.5 s counted
    p.burst(1.0, 1.0)  # waits 0.5, runs [1.5, 2.5): 0.5 s counted
    p.burst(3.0, 1.0)  # after the window: nothing
    assert p.busy == 1.0
    assert p.bursts == 1
    assert p.max_wait == 0.5
    rep = cpu.report().processes[1]
    assert (rep.name, rep.busy, rep.max_wait, rep.bursts) == ("server", 1.0, 0.5, 1)


def test_no_cpu_stage_has_no_cpu() -> None:
    with pytest.raises(ValueError, match="preset 'none'"):
        Cpu(DeploymentSpec(), 1, 0.0, 1.0)


def test_queue_wait_is_erlang_c_by_hand() -> None:
    # M/M/1: rho / (1 - rho); M/M/2 at 0.5: C = 1/3, W/S = C / (2 * 0.5) = 1/3
    assert queue_wait(1, 0.5) == pytest.approx(1.0, rel=1e-15)
    assert queue_wait(1, 0.75) == pytest.approx(3.0, rel=1e-15)
    assert queue_wait(2, 0.5) == pytest.approx(1.0 / 3.0, rel=1e-15)
    assert queue_wait(2, 0.0) == 0.0
    assert queue_wait(1, 0.999) == queue_wait(1, U_CAP) == pytest.approx(19.0)


def _runq(**kw: float | bool) -> Cpu:
    return Cpu(DeploymentSpec(preset="colocated", cores=1, **kw), 1, 0.0, 100.0)  # type: ignore[arg-type]


def test_a_run_queue_floor_delays_each_burst_by_its_share_of_the_burst() -> None:
    cpu = _runq(server_runq=0.5)
    s = cpu.server
    assert s.span(1.0, 0.2) == (1.1, pytest.approx(1.3))  # waits 0.5 x 0.2 first
    # queued behind itself: ready at 1.3, waits 0.5 x 0.4 more, runs 0.4
    start, end = s.span(1.0, 0.4)
    assert (start, end) == (pytest.approx(1.5), pytest.approx(1.9))
    assert s.queued == pytest.approx(0.1 + 0.2)
    assert cpu.hosts[0].burst(1.0, 0.1) == pytest.approx(1.1)  # no floor: the core at once


def test_growth_follows_the_last_windows_utilisation() -> None:
    """One core, growth on: 0.025 CPU-s arriving in [0, 0.05) is utilisation 0.5, so a
    burst in the next window waits queue_wait(1, 0.5) = 1 times its length; a window
    with nothing before it waits nothing."""
    cpu = _runq(runq_growth=True)
    h = cpu.hosts[0]
    assert h.burst(0.0, 0.025) == 0.025  # the first window: no history, no wait
    start, _end = h.span(LOAD_WINDOW + 0.01, 0.001)
    assert start == pytest.approx(LOAD_WINDOW + 0.01 + 1.0 * 0.001)
    start, _end = h.span(3 * LOAD_WINDOW + 0.001, 0.002)  # the window before was empty
    assert start == 3 * LOAD_WINDOW + 0.001


def test_broker_growth_alone_the_hosts_burst_counts_in_the_window_but_waits_no_queue(
) -> None:
    """One core, ``broker_runq_growth``: a host's 0.025 CPU-s in [0, 0.05) makes the next
    window's utilisation 0.5 for every process on the machine, but only the broker's
    burst waits queue_wait(1, 0.5) = 1 times its length; the host's starts at once."""
    cpu = _runq(broker_runq_growth=True)
    h, b = cpu.hosts[0], cpu.broker
    assert (b.grow, h.grow, cpu.server.grow) == (True, False, False)
    assert h.burst(0.0, 0.025) == 0.025
    start, _end = h.span(LOAD_WINDOW + 0.01, 0.001)
    assert start == LOAD_WINDOW + 0.01
    start, _end = b.span(LOAD_WINDOW + 0.02, 0.002)
    assert start == pytest.approx(LOAD_WINDOW + 0.02 + 1.0 * 0.002)
    assert (b.queued, h.queued) == (pytest.approx(0.002), 0.0)


def test_server_growth_as_calibrate_writes_it_the_hosts_wait_no_queue() -> None:
    """One core, broker and server growth (as ``calibrate`` writes them): a host's
    0.025 CPU-s in [0, 0.05) makes the next window's utilisation 0.5; the server's
    burst there waits queue_wait(1, 0.5) = 1 times its length on top of its floor
    (0.5 x 0.004), the host's starts at once."""
    cpu = _runq(broker_runq_growth=True, server_runq_growth=True, server_runq=0.5)
    h, s = cpu.hosts[0], cpu.server
    assert (cpu.broker.grow, s.grow, h.grow) == (True, True, False)
    assert h.burst(0.0, 0.025) == 0.025
    start, _end = h.span(LOAD_WINDOW + 0.01, 0.001)
    assert start == LOAD_WINDOW + 0.01
    start, _end = s.span(LOAD_WINDOW + 0.02, 0.004)
    assert start == pytest.approx(LOAD_WINDOW + 0.02 + (0.5 + 1.0) * 0.004)
    assert (s.queued, h.queued) == (pytest.approx(0.006), 0.0)


def test_a_wake_ups_side_part_takes_a_core_but_not_the_thread() -> None:
    """One core, server demand 0.2, wake 0.1, side 0.3, run-queue floor 0.5. The first
    burst (arrival 1.0) wakes the thread: its side part takes the core [1.0, 1.3); the
    thread's own burst (0.3 long) waits 0.5 x 0.3 = 0.15 on the run queue (per its own
    length, not the side's), ready at 1.15, but the core is held until 1.3: [1.3, 1.6).
    A second burst at 1.35 finds the thread busy: no wake-up, no side part; ready at
    1.6 + 0.5 x 0.2 = 1.7, runs [1.7, 1.9). The process's CPU is all three parts; the
    machine's load window counts the side's CPU too."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=1, server_demand=0.2, server_wake=0.1,
                             server_wake_side=0.3, server_runq=0.5, host_demand=0.1),
              1, 0.0, 100.0)
    s = cpu.server
    assert s.span(1.0, 0.2) == (pytest.approx(1.3), pytest.approx(1.6))
    assert s.span(1.35, 0.2) == (pytest.approx(1.7), pytest.approx(1.9))
    assert s.busy == pytest.approx(0.3 + 0.3 + 0.2)
    assert s.queued == pytest.approx(0.15 + 0.1)
    # [1.0, 1.3) ended by the second arrival and was dropped
    assert s.machine.cores[0] == [pytest.approx((1.3, 1.6)), pytest.approx((1.7, 1.9))]
    assert s.machine.w_busy == pytest.approx(0.3 + 0.3 + 0.2)


def test_side_part_runs_beside_the_thread_on_a_second_core() -> None:
    """Two cores, host wake 0.1 with side 0.4: the side part and the thread's burst
    start together at the arrival, on cores 0 and 1; the thread is free at 0.35, so a
    burst at 0.4 wakes it again (both reservations ended by then: the side part on
    core 0, the thread's burst on core 1)."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, host_demand=0.25, host_wake=0.1,
                             host_wake_side=0.4), 1, 0.0, 100.0)
    h = cpu.hosts[0]
    assert h.span(0.0, 0.25) == (0.0, pytest.approx(0.35))
    assert h.machine.cores == [[(0.0, 0.4)], [(0.0, pytest.approx(0.35))]]
    assert h.span(0.4, 0.25) == (pytest.approx(0.4), pytest.approx(0.75))
    assert h.machine.cores == [[(0.4, pytest.approx(0.8))], [(0.4, pytest.approx(0.75))]]
    assert h.busy == pytest.approx(2 * (0.35 + 0.4))


def test_a_side_part_needs_a_wake_up() -> None:
    with pytest.raises(ConfigError, match="host_wake_side.*needs deployment.host_wake > 0"):
        DeploymentSpec(preset="colocated", host_demand=0.1, host_wake_side=0.1)


def test_a_network_thread_serves_its_own_bursts_in_arrival_order() -> None:
    """Two cores, server net_msg 0.1, net_wake 0.2. A copy at 1.0 finds the network
    thread idle: 0.3 long, [1.0, 1.3). A copy at 1.1 finds it busy: no wake-up, ready at
    1.3, [1.3, 1.4). A copy at 2.0 wakes it again: [2.0, 2.3). The loop thread is
    untouched (free still -inf) and a loop burst at 1.0 runs beside on the other core."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, server_demand=0.25,
                             server_net_msg=0.1, server_net_wake=0.2), 1, 0.0, 100.0)
    s = cpu.server
    assert s.threaded and not cpu.hosts[0].threaded
    assert s.net_span(1.0, False) == (1.0, pytest.approx(1.3))
    assert s.net_span(1.1, False) == (pytest.approx(1.3), pytest.approx(1.4))
    assert s.span(1.0, 0.25) == (1.0, 1.25)  # core 1: the loop thread is another thread
    assert s.net_span(2.0, False) == (2.0, pytest.approx(2.3))
    assert s.busy == pytest.approx(0.3 + 0.1 + 0.25 + 0.3)


def test_a_received_copy_waits_for_the_interpreter_lock_at_most_the_switch() -> None:
    """Two cores, lock switch 0.05. The loop thread is busy [0, 1). A received copy at
    0.2 (``gil``) waits for the lock: the loop frees at 1.0, but the switch is due at
    0.25, so it runs [0.25, 0.35); a copy to send (no ``gil``) at 0.3 only waits for the
    network thread: [0.35, 0.45). With the loop idle a received copy starts at once."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, server_demand=1.0,
                             server_net_msg=0.1, lock_switch=0.05), 1, 0.0, 100.0)
    s = cpu.server
    assert s.span(0.0, 1.0) == (0.0, 1.0)
    assert s.net_span(0.2, True) == (pytest.approx(0.25), pytest.approx(0.35))
    assert s.net_span(0.3, False) == (pytest.approx(0.35), pytest.approx(0.45))
    assert s.net_span(2.0, True) == (2.0, pytest.approx(2.1))


@pytest.mark.parametrize(("switch", "start"), [(0.05, 0.15), (0.5, 0.3), (0.0, 0.1)])
def test_the_loop_thread_waits_for_the_lock_the_network_thread_holds(
        switch: float, start: float) -> None:
    """Two cores; the network thread's burst [0, 0.3) holds the interpreter lock. A loop
    burst of 1.0 at 0.1 waits for it until the switch interval has passed (0.05: from
    0.15) or the network thread is done (0.5: from 0.3); without a lock (switch 0) it
    runs at once on the other core."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, server_demand=1.0,
                             server_net_msg=0.3, lock_switch=switch), 1, 0.0, 100.0)
    s = cpu.server
    assert s.net_span(0.0, False) == (0.0, pytest.approx(0.3))
    assert s.span(0.1, 1.0) == (pytest.approx(start), pytest.approx(start + 1.0))


def test_a_network_thread_burst_waits_on_the_run_queue_as_any_burst() -> None:
    """One core, run-queue floor 0.5: a network-thread burst of 0.2 arriving at 1.0
    waits 0.5 x 0.2 = 0.1 before it runs [1.1, 1.3)."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=1, host_demand=0.1, host_net_msg=0.2,
                             host_runq=0.5), 1, 0.0, 100.0)
    h = cpu.hosts[0]
    assert h.net_span(1.0, False) == (pytest.approx(1.1), pytest.approx(1.3))
    assert h.queued == pytest.approx(0.1)


def test_a_network_thread_needs_a_demand() -> None:
    with pytest.raises(ConfigError, match="server_net_wake.*needs deployment.server_demand"):
        DeploymentSpec(preset="colocated", server_net_wake=0.1)


def test_a_wait_for_the_lock_is_a_network_wake_up_and_places_the_side_part() -> None:
    """Two cores; server demand 1.0 with wake 0.05 and side 0.3, network thread 0.1 a
    message and 0.2 a wake-up, lock switch 0.05. The loop's burst [0, 1.05) (a wake-up;
    no side part on the loop thread of a process with a network thread) holds core 0. A
    copy at 0.2 finds the network thread idle and the loop busy: it waits for the lock
    until 0.25; its side part takes core 1 from the arrival, [0.2, 0.5), so its own
    0.3 runs [0.5, 0.8). A copy at 0.6 finds the network thread busy until 0.8 and then
    the loop still busy: it waits for the lock until 0.85, which is a wake-up again
    (the thread blocked): side [0.8, 1.1) on core 1, its burst on core 0 at 1.05."""
    cpu = Cpu(DeploymentSpec(preset="colocated", cores=2, server_demand=1.0, server_wake=0.05,
                             server_wake_side=0.3, server_net_msg=0.1, server_net_wake=0.2,
                             lock_switch=0.05), 1, 0.0, 100.0)
    s = cpu.server
    assert s.span(0.0, 1.0) == (0.0, pytest.approx(1.05))
    assert s.net_span(0.2, True) == (pytest.approx(0.5), pytest.approx(0.8))
    assert s.net_span(0.6, True) == (pytest.approx(1.05), pytest.approx(1.35))
    assert s.machine.cores[1] == [pytest.approx((0.5, 0.8)), pytest.approx((0.8, 1.1))]
    assert s.busy == pytest.approx(1.05 + 2 * (0.3 + 0.3))


@pytest.mark.parametrize("key", ["host_net_msg", "server_net_msg", "host_net_wake",
                                 "server_net_wake"])
def test_network_thread_keys_refused_out_of_range_and_without_a_stage(key: str) -> None:
    who = key.split("_")[0]
    ok = {f"{who}_demand": 1e-4}
    with pytest.raises(ConfigError, match=rf"{key}.*must be in \[0, 1\]"):
        DeploymentSpec(preset="colocated", **ok, **{key: 1.5})
    with pytest.raises(ConfigError, match=rf"{key}.*must be in \[0, 1\]"):
        DeploymentSpec(preset="colocated", **ok, **{key: -1e-6})
    # without a CPU stage there is no demand, which the key needs (named)
    with pytest.raises(ConfigError, match=rf"{key}: needs deployment.{who}_demand > 0"):
        DeploymentSpec(preset="none", **{key: 1e-4})
