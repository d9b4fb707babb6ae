"""Bundled PUBLISHes, live and DES (studies/validation/bundles.py): the live turns
reconstructed from hand-built completion rows, their statistics and lateness by hand,
and the DES's turns on a tiny bundled scenario whose bundles are known exactly."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from sigma_lab.studies.validation.bundles import (
    GAP_S,
    des_turns,
    live_lateness,
    live_turns,
    turn_stats,
)

from sigma_des.config import Scenario, with_overrides
from sigma_des.net import cpu as cpumod
from sigma_des.net.network import Network

COLS = ["method", "kind", "host", "node", "frame", "t_send", "t_recv", "t_trig", "cost",
        "republish"]


def _pub(host: int, node: int, t: float, t_trig: float = math.nan, cost: float = math.nan,
         method: str = "none", kind: str = "state_pub") -> tuple[object, ...]:
    return (method, kind, host, node, 7, t, math.nan, t_trig, cost, 0.0)


def _msgs() -> pd.DataFrame:
    """Host 0: completions at 1.000000, +10 µs, +30 µs (one turn: gaps 10 and 20 µs),
    1.001000 and +50 µs (a second turn: 970 µs, then 50 µs), 1.002000 (a third).
    Host 1: one completion at 1.5. Left out: a completion before the window (0.9),
    one of another method, a server receipt row."""
    rows = [_pub(0, 0, 1.0), _pub(0, 1, 1.00001), _pub(0, 2, 1.00003), _pub(0, 3, 1.001),
            _pub(0, 4, 1.00105), _pub(0, 5, 1.002), _pub(1, 9, 1.5), _pub(0, 0, 0.9),
            _pub(0, 1, 1.2, method="hlc"), _pub(0, 1, 1.3, kind="state")]
    return pd.DataFrame(rows, columns=COLS)


def test_live_turns_split_where_completions_are_more_than_the_gap_apart() -> None:
    assert GAP_S == pytest.approx(60e-6)
    turns = live_turns(_msgs(), "none", 1.0, 3.0)
    assert turns == {0: [(1.0, 3), (1.001, 2), (1.002, 1)], 1: [(1.5, 1)]}
    # 15 µs: the 10 µs gap keeps the first two together, the 20 and 50 µs gaps split
    assert live_turns(_msgs(), "none", 1.0, 3.0, gap_s=15e-6)[0] == [
        (1.0, 2), (1.00003, 1), (1.001, 1), (1.00105, 1), (1.002, 1)]


def test_turn_stats_by_hand() -> None:
    """Sizes 3, 2, 1 and 1 over a 2 s window and 2 hosts: 7/4 records a PUBLISH, 1
    PUBLISH a second and host; host 0's gaps 1.0 and 1.0 ms (host 1 has none)."""
    st = turn_stats(live_turns(_msgs(), "none", 1.0, 3.0), 2.0)
    assert st["records_per_publish"] == pytest.approx(7 / 4)
    assert st["hist"] == [2, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    assert st["publish_hz_per_host"] == pytest.approx(1.0)
    assert st["gap_ms_mean"] == pytest.approx(1.0)
    assert st["gap_ms_median"] == pytest.approx(1.0)


def test_live_lateness_of_the_jobs_started_at_the_trigger() -> None:
    """Two cores: the first two nodes of each host (by node id) started at the trigger's
    handling; node 0 due at 1.0 + 0.5 ms, run at 1.0007 (200 µs late); node 1 due at
    1.0008, run at 1.0008 (on time); node 2 (third on its host) is left out, and so is a
    row whose trigger is newer than its job (negative lateness)."""
    rows = [_pub(0, 0, 1.0007, 1.0, 0.0005), _pub(0, 1, 1.0008, 1.0, 0.0008),
            _pub(0, 2, 1.0030, 1.0, 0.0005), _pub(1, 5, 1.0100, 1.0105, 0.0005)]
    late = live_lateness(pd.DataFrame(rows, columns=COLS), "none", 1.0, 2.0, 2)
    np.testing.assert_allclose(np.sort(late), [0.0, 200e-6], atol=1e-12)


def _tiny(*sets: str) -> Scenario:
    return with_overrides(Scenario(), [
        "nodes=4", "hosts=2", "duration=1.0", "warmup=0.5", "fidelity.enabled=false",
        'compute.step_time.dist="constant"', "compute.step_time.value=0.001",
        'deployment.clients="host"', "deployment.bundle=true", *sets])


def test_des_turns_without_a_cpu_stage_bundle_one_instant() -> None:
    """Constant step times and no CPU stage: a host's two nodes finish at one instant,
    so each of the 2 host clients sends one PUBLISH of 2 records a frame (100 Hz), 10 ms
    apart; no publish burst is counted (no process)."""
    turns, bw, figs = des_turns(_tiny(), "none")
    assert sorted(turns) == [0, 2]
    st = turn_stats(turns, 0.5)
    assert st["records_per_publish"] == 2.0
    assert st["publish_hz_per_host"] == pytest.approx(100.0)
    assert st["gap_ms_median"] == pytest.approx(10.0)
    assert bw.bursts == 0
    assert figs["missed_frac"] == 0.0


def test_des_turns_count_the_publish_bursts_and_restore_the_classes() -> None:
    """With a CPU stage (host demand 0.5 ms, no record cost, waits or lock): host 0's 50
    PUBLISHes in the 0.5 s window are 50 bursts of 0.5 ms run and no wait; the patched
    methods are the classes' own again afterwards."""
    before = (cpumod.Process.acquire, cpumod.Process.net_span, Network._flush,
              Network._client_publish)
    _turns, bw, _figs = des_turns(_tiny('deployment.preset="colocated"',
                                        "deployment.host_demand=0.0005",
                                        "deployment.server_demand=0.0001"), "none")
    assert bw.bursts == 50
    assert bw.run == pytest.approx(50 * 0.0005)
    assert bw.lock == bw.runq == bw.core == 0.0
    assert (cpumod.Process.acquire, cpumod.Process.net_span, Network._flush,
            Network._client_publish) == before
