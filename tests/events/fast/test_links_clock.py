"""The compiled core's link and clock tables against the per-message objects, exactly.

Gilbert–Elliott chain state (:meth:`sigma_des.net.loss.LossProcess.bad_state`),
degrade windows, drop keys and NTP-corrected clocks
(:meth:`sigma_des.net.clocks.NodeClocks.local_time`): the compiled functions read
the tables Python builds from the very objects the per-message engine uses.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.clock import local_time, sync_index
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.loss import forced_drop, link_loss
from sigma_des.events.fast.support import TABLE_MARGIN, ge_slots, ntp_syncs
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.net.kinds import COMMAND, STATE, TRIGGER
from tests.conftest import tiny

_GE = {"model": "gilbert_elliott", "p_gb": 0.2, "p_bg": 0.3, "loss_good": 0.05,
       "loss_bad": 0.7, "slot": 0.003}


def _run(**over: Any) -> tuple[MethodRun, CompiledCore]:
    sc = replace(tiny(**{"net.transport": "datagram", **over}), engine="cohort")
    run = MethodRun(sc.run_spec(), "hlc", make_dynamics(sc), make_behaviour(sc), compiled=True)
    assert isinstance(run.core, CompiledCore)
    return run, run.core


def test_gilbert_elliott_state_matches_the_loss_process_at_random_times() -> None:
    run, core = _run(**{"net.host_link.loss": _GE,
                        "net.server_link.loss": {**_GE, "slot": 0.01, "p_gb": 0.5}})
    S = core.S
    n = run.n
    assert S[L.GE_BAD].shape == (2, 3, ge_slots(run.spec))
    rng = np.random.default_rng(7)
    times = np.concatenate([rng.uniform(0.0, 1.0 + TABLE_MARGIN, 300),
                            np.arange(0, 300) * 0.003, np.arange(0, 100) * 0.01])
    seen_bad = 0
    for client in range(n + 1):
        cls = int(client == n)
        spec = (_GE if cls == 0 else {**_GE, "loss_good": 0.05, "loss_bad": 0.7})
        link = run.net.link_of[client]
        for up in (0, 1):
            proc = run.net.loss_process(cls == 1, up == 1, link)
            bad = proc.bad_state(times)
            seen_bad += int(bad.sum())
            for t, b in zip(times, bad, strict=True):
                p, extra = link_loss(S, client, cls, up, float(t))
                assert p == (spec["loss_bad"] if b else spec["loss_good"]) and extra == 0.0
    assert 0 < seen_bad < 2 * (n + 1) * times.size  # both states occur
    assert S[L.INTS][CO.I_ERR] == 0
    link_loss(S, 0, 0, 1, 1.0 + TABLE_MARGIN + 0.01)  # beyond the table
    assert S[L.INTS][CO.I_ERR] == L.ERR_HORIZON


def test_degrade_windows_add_delay_and_combine_loss_in_fault_order() -> None:
    faults = [
        {"kind": "degrade", "host": 0, "start": 0.2, "end": 0.6, "extra_delay": 0.004,
         "extra_loss": 0.2},
        {"kind": "degrade", "host": 0, "start": 0.4, "end": 0.8, "extra_delay": 0.001,
         "extra_loss": 0.1},
        {"kind": "degrade", "host": 1, "start": 0.1, "end": 0.5, "extra_delay": 0.003},
    ]
    run, core = _run(faults=faults, **{"net.host_link.loss": {"p": 0.05}})
    S = core.S
    node0 = run.spec.host_of.index(0)
    node1 = run.spec.host_of.index(1)


    def comb(p: float, q: float) -> float:
        return 1.0 - (1.0 - p) * (1.0 - q)

    for up in (0, 1):
        assert link_loss(S, node0, 0, up, 0.1) == (0.05, 0.0)
        assert link_loss(S, node0, 0, up, 0.3) == (comb(0.05, 0.2), 0.004)
        # both windows, combined in fault order
        assert link_loss(S, node0, 0, up, 0.5) == (comb(comb(0.05, 0.2), 0.1), 0.004 + 0.001)
        assert link_loss(S, node0, 0, up, 0.6) == (comb(0.05, 0.1), 0.001)  # end excluded
        # a delay-only window still recombines p (0.05 becomes 0.050000000000000044)
        assert link_loss(S, node1, 0, up, 0.1) == (comb(0.05, 0.0), 0.003)
        assert comb(0.05, 0.0) != 0.05
        assert link_loss(S, node1, 0, up, 0.5) == (0.05, 0.0)
        assert link_loss(S, run.n, 1, up, 0.3) == (0.0, 0.0)  # the server's link


def test_drop_keys_are_found_on_the_downlink_only() -> None:
    faults = [
        {"kind": "drop", "node": 1, "frame": 20, "message": "state"},
        {"kind": "drop", "node": 0, "frame": 10, "message": "trigger"},
        {"kind": "drop", "node": 2, "frame": 3, "message": "command"},
        {"kind": "drop", "node": 2, "frame": 4, "message": "command"},
    ]
    _run_, core = _run(faults=faults)
    S = core.S
    keys = {(STATE, 1, 20), (TRIGGER, 0, 10), (COMMAND, 2, 3), (COMMAND, 2, 4)}
    assert [tuple(r) for r in S[L.DROPS]] == sorted(keys)
    for kind in (TRIGGER, STATE, COMMAND):
        for subj in range(3):
            for index in range(25):
                key = (int(kind), subj, index)
                assert forced_drop(S, 0, *key) == (key in keys), key
                assert not forced_drop(S, 1, *key)


@pytest.mark.parametrize("period", [0.1, 0.3, 1.0 / 3.0])
def test_ntp_local_time_matches_the_node_clocks_exactly(period: float) -> None:
    run, core = _run(**{"clocks.offset_std": 0.002, "clocks.drift_ppm_std": 100.0,
                        "clocks.ntp_period": period, "clocks.ntp_residual_std": 1e-4})
    S = core.S
    clocks = run.nodes.clocks
    assert S[L.NTP_RES].shape == (run.n, ntp_syncs(run.spec))
    rng = np.random.default_rng(3)
    j = np.arange(0, 8)
    times = np.concatenate([rng.uniform(0.0, 1.0 + TABLE_MARGIN, 200), j * period,
                            np.nextafter(j * period, -1.0)])
    times = times[times >= 0.0]
    for i in range(run.n):
        want = clocks.local_time(i, times)
        got = np.array([local_time(S, i, float(t)) for t in times])
        np.testing.assert_array_equal(got, want)
        assert np.array_equal(
            [sync_index(float(t), period) for t in times], clocks.sync_index(times)
        )
    assert S[L.INTS][CO.I_ERR] == 0
    local_time(S, 0, 1.0 + TABLE_MARGIN + 2 * period)
    assert S[L.INTS][CO.I_ERR] == L.ERR_HORIZON


def test_without_ntp_local_time_is_offset_and_drift() -> None:
    run, core = _run(**{"clocks.offset_std": 0.002, "clocks.drift_ppm_std": 100.0})
    clocks = run.nodes.clocks
    for i in range(run.n):
        for t in (0.0, 0.25, 0.9):
            assert local_time(core.S, i, t) == clocks.local_time(i, t)
