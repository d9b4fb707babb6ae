"""The payload pool: a slot's payload is a pool row, taken and freed with the slot, copied
with it, and the pool grows in place (issue 27, "memory")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import driver
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.growth import grow
from sigma_des.events.fast.primitives import alloc, give_payload, payload, release
from sigma_des.events.fast.transport import copy_slot
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.fast.test_growth import _state


def test_a_payload_row_is_taken_copied_freed_and_reused_with_its_slot() -> None:
    S = _state()  # 5 slots, 4 payload rows of 12 floats, all free
    iv, evi, pool = S[L.INTS], S[L.EV_INT], S[L.POOL]
    s0 = alloc(S)
    r0 = give_payload(S, s0)
    assert (s0, r0, evi[s0, CO.E_PAY], iv[CO.I_PFREE]) == (0, 0, 1, 3)
    pool[r0] = np.arange(1.0, 13.0)
    S[L.EV_FLOAT][s0] = [0.5, 1.5, 2.5, 3.5]
    s1 = alloc(S)
    copy_slot(S, s0, s1)  # a copy of its own: row 1, the same values
    assert (s1, payload(S, s1), iv[CO.I_PFREE]) == (1, 1, 2)
    assert pool[1].tolist() == list(np.arange(1.0, 13.0))
    assert S[L.EV_FLOAT][s1].tolist() == [0.5, 1.5, 2.5, 3.5]
    s2 = alloc(S)  # a trigger: no payload
    assert evi[s2, CO.E_PAY] == 0
    release(S, s2)
    assert iv[CO.I_PFREE] == 2  # no row given back
    pool[r0] = -7.0  # the copy does not share the original's row
    assert pool[1].tolist() == list(np.arange(1.0, 13.0))
    release(S, s0)  # its row goes back on top of the pool's free list
    assert (iv[CO.I_PFREE], S[L.POOL_FREE][2], evi[s0, CO.E_PAY]) == (3, 0, 0)
    s3 = alloc(S)
    assert s3 == s0 and evi[s3, CO.E_PAY] == 0  # a freed slot carries no payload
    assert give_payload(S, s3) == 0  # the freed row, taken first
    release(S, s1)
    release(S, s3)
    assert (iv[CO.I_FREE], iv[CO.I_PFREE]) == (5, 4)
    assert sorted(S[L.POOL_FREE].tolist()) == [0, 1, 2, 3]


def test_the_pool_grows_in_place_keeping_its_rows() -> None:
    S = _state()
    pool, free = S[L.POOL], S[L.POOL_FREE]
    for k in range(3):
        s = alloc(S)
        pool[give_payload(S, s)] = 10.0 * (k + 1)
    assert S[L.INTS][CO.I_PFREE] == 1
    T = grow(S, 2)  # 4 rows + max(4 // 8, 2) = 6; 2 slots are free: the slots stay
    assert T[L.POOL] is pool and T[L.POOL_FREE] is free and pool.shape == (6, 12)
    assert T[L.EV_INT].shape == (5, CO.E_COLS) and T[L.INTS][CO.I_FREE] == 2
    assert pool[:3, 0].tolist() == [10.0, 20.0, 30.0] and not pool[3:].any()
    # the new rows on top of the free list, lowest first
    assert T[L.INTS][CO.I_PFREE] == 3 and free.tolist()[:3] == [3, 5, 4]
    assert [give_payload(T, s) for s in (3, 4)] == [4, 5]


def test_the_backlog_of_a_saturated_broker_keeps_every_payload_in_its_own_row(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Mid-run, every in-flight slot that carries a payload holds its own row, the rows in
    use and the free ones are the whole pool, and each state in flight (copied by the
    broker for its subscriber) still carries its frame's observation from the ring."""
    monkeypatch.setattr(driver, "SLACK", 0)  # the pool starts at 28 rows: it grows
    sc = replace(tiny(nodes=6, **{"broker.delivery_service": 0.002, "commands.enabled": True}),
                 engine="cohort")
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc), compiled=True)
    core = run.core
    assert isinstance(core, CompiledCore)
    rows0 = core.array("pool").shape[0]
    checked = {"states": 0, "commands": 0, "rows": 0}

    def check(_t: float) -> None:
        evi, pool = core.array("ev_int"), core.array("pool")
        iv = core.array("ints")
        free_slots = set(core.array("free")[: iv[CO.I_FREE]].tolist())
        live = [s for s in range(evi.shape[0]) if s not in free_slots]
        assert all(evi[s, CO.E_PAY] == 0 for s in free_slots)
        used = [int(evi[s, CO.E_PAY]) - 1 for s in live if evi[s, CO.E_PAY] > 0]
        free_rows = core.array("pool_free")[: iv[CO.I_PFREE]].tolist()
        assert len(set(used)) == len(used)
        assert sorted(used + free_rows) == list(range(pool.shape[0]))
        checked["rows"] = max(checked["rows"], pool.shape[0])
        frames, ring = core.array("slot_frame"), core.array("obs_hist")
        for s in live:
            kind = evi[s, CO.E_KIND]
            assert (evi[s, CO.E_PAY] > 0) == (kind in (CO.K_STATE, CO.K_COMMAND, CO.K_REPUB))
            if kind == CO.K_COMMAND:
                checked["commands"] += 1
            sl = evi[s, CO.E_FRAME] % frames.size
            if kind == CO.K_STATE and frames[sl] == evi[s, CO.E_FRAME]:
                row = pool[evi[s, CO.E_PAY] - 1, : ring.shape[2]]
                assert row.tolist() == ring[sl, evi[s, CO.E_SUBJ]].tolist()
                checked["states"] += 1

    run.run(check)
    assert core.array("pool").size == 0  # dropped with the event table
    assert checked["states"] > 100 and checked["commands"] > 0
    assert rows0 == 4 * 7 < checked["rows"]  # as many rows as slots at first, then grown
