"""The event table's growth, its payload pool and the range checks of its int32 columns,
by hand."""

from __future__ import annotations

import gc
import subprocess
import sys
import weakref
from dataclasses import replace

import numpy as np
import pytest

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.growth import (
    COLLECT_FROM,
    IN_PLACE,
    PREFIX,
    SCRATCH,
    before_run,
    fresh,
    grow,
    grown_capacity,
    run_finished,
)
from sigma_des.events.fast.primitives import put_int
from sigma_des.events.fast.support import CohortFallback, checked_int
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.fast.test_layout import DIMS as LAYOUT_DIMS

DIMS = {**LAYOUT_DIMS, "cap": 5, "arena": 10}  # the arena twice the table (a run: 1.25x)


def _state() -> tuple[np.ndarray, ...]:
    given = {f.name: np.zeros(L.shape_of(f, DIMS), dtype=f.dtype)
             for f in L.FIELDS if f.fill is None}
    given["free"] = np.arange(5, dtype=np.int64)[::-1].copy()
    given["pool_free"] = np.arange(4, dtype=np.int32)[::-1].copy()
    S = L.allocate(DIMS, given)
    S[L.INTS][CO.I_FREE], S[L.INTS][CO.I_PFREE] = 5, 4
    return S


def test_capacity_grows_by_an_eighth_or_what_is_needed() -> None:
    assert grown_capacity(1000, 10) == 1125  # 1000 // 8
    assert grown_capacity(1000, 300) == 1300  # the need is larger
    assert grown_capacity(7, 3) == 10  # 7 // 8 = 0
    assert grown_capacity(CO.MAX_SLOTS - 8, 1) == CO.MAX_SLOTS  # an eighth would be more
    assert grown_capacity(CO.MAX_SLOTS - 8, 8) == CO.MAX_SLOTS
    with pytest.raises(CohortFallback, match=f"more than {CO.MAX_SLOTS} messages in flight"):
        grown_capacity(CO.MAX_SLOTS - 8, 9)


def test_every_array_of_table_rows_has_exactly_one_growth_rule() -> None:
    rows = {f.name for f in L.FIELDS if f.shape[:1] in (("cap",), ("arena",))}
    rules = [*IN_PLACE, *PREFIX, *SCRATCH]
    assert len(rules) == len(set(rules)) and set(rules) == rows


def test_growth_keeps_slots_live_prefixes_and_the_free_list() -> None:
    S = _state()
    evi, evf, run_t = S[L.EV_INT], S[L.EV_FLOAT], S[L.RUN_T]
    evi[:] = np.arange(5 * CO.E_COLS).reshape(5, CO.E_COLS)
    evf[:] = np.arange(5 * 4).reshape(5, 4) / 4
    run_t[:] = np.arange(10) + 0.5
    S[L.HEAP_T][:] = [1.0, 2.0, 9.0, 9.0, 9.0]  # two live heap entries, then stale ones
    S[L.PEND_K][:] = [7, 8, 8, 8, 8]
    S[L.RUN_POS][:] = [3, 4, 5, 6, 6]
    S[L.BOUNDS][:] = 1
    qi = S[L.Q_INT]
    qi[CO.QI_HEAP], qi[CO.QI_PN], qi[CO.QI_NRUN] = 2, 1, 3
    S[L.INTS][CO.I_FREE] = 2  # slots 4 and 3 free, 0..2 in flight
    T = grow(S, 3)  # 5 slots + max(5 // 8, 3) = 8
    assert T[L.EV_INT] is evi and T[L.EV_FLOAT] is evf and T[L.RUN_T] is run_t  # in place
    assert evi.shape == (8, CO.E_COLS) and evf.shape == (8, 4) and run_t.shape == (16,)
    assert evi[:5].ravel().tolist() == list(range(5 * CO.E_COLS)) and not evi[5:].any()
    assert evf[4, 3] == 19 / 4 and run_t[:10].tolist() == [i + 0.5 for i in range(10)]
    assert T[L.HEAP_T].tolist() == [1.0, 2.0, 0, 0, 0, 0, 0, 0]
    assert T[L.PEND_K].tolist() == [7, 0, 0, 0, 0, 0, 0, 0]
    assert T[L.RUN_POS].tolist() == [3, 4, 5, 0, 0, 0, 0, 0]
    assert T[L.BOUNDS].shape == (16,) and not T[L.BOUNDS].any()
    # the new slots on top of the free list, lowest taken first
    assert T[L.INTS][CO.I_FREE] == 5 and T[L.FREE][:5].tolist() == [4, 3, 7, 6, 5]


def test_a_run_state_grows_and_keeps_its_results() -> None:
    sc = replace(tiny(nodes=6, **{"broker.delivery_service": 0.0008}), engine="cohort")
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc), compiled=True)
    core = run.core
    assert isinstance(core, CompiledCore)
    cap0 = core.array("ev_int").shape[0]
    core.ensure_space(cap0)  # more free slots than the table has: it grows
    assert core.array("ev_int").shape[0] == grown_capacity(cap0, cap0 + 6 + 4)
    assert int(core.array("ints")[CO.I_FREE]) == core.array("ev_int").shape[0]


def test_a_value_beyond_int32_is_an_error_not_a_wrapped_store() -> None:
    S = _state()
    put_int(S, 2, CO.E_AUX, L.EV_INT_MAX)
    put_int(S, 3, CO.E_SEQ, -L.EV_INT_MAX - 1)
    assert S[L.EV_INT][2, CO.E_AUX] == 2**31 - 1 and S[L.EV_INT][3, CO.E_SEQ] == -(2**31)
    assert S[L.INTS][CO.I_ERR] == 0
    put_int(S, 2, CO.E_AUX, 2**31)
    assert S[L.INTS][CO.I_ERR] == L.ERR_RANGE and S[L.EV_INT][2, CO.E_AUX] == 2**31 - 1


def test_a_publish_index_beyond_int32_falls_back_with_its_name() -> None:
    assert checked_int(2**31 - 1, "trigger index") == 2**31 - 1
    with pytest.raises(CohortFallback, match=r"re-request index 2147483648 beyond the event "
                       r"table's int32 columns \(largest 2147483647\)"):
        checked_int(2**31, "re-request index")
    sc = replace(tiny(), engine="cohort")
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc), compiled=True)
    assert isinstance(run.core, CompiledCore)
    with pytest.raises(CohortFallback, match="trigger index 2147483648 beyond"):
        run.core.publish_trigger(2**31, None)


def test_a_finished_run_lets_go_of_its_event_table() -> None:
    sc = replace(tiny(nodes=6, **{"broker.delivery_service": 0.002}), engine="cohort")
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc), compiled=True)
    core = run.core
    assert isinstance(core, CompiledCore)
    in_flight: list[int] = []
    run.run(lambda t: in_flight.append(
        core.array("ev_int").shape[0] - int(core.array("ints")[CO.I_FREE])))
    assert in_flight[-1] > 100  # the broker's backlog at the end, not read by any result
    assert core.array("ev_int").shape == (0, CO.E_COLS) and core.array("run_t").size == 0
    # the core let go of the physics ring it shared, and the run released it (its frames
    # are in the fidelity log: SwarmTruth.release)
    assert core.array("obs_hist").size == 0 and run.truth.obs_hist.size == 0
    assert run.trajectory()[0].size > 1
    with pytest.raises(RuntimeError, match="the run is over: its message core is closed"):
        core.publish_trigger(10**6, None)


@pytest.mark.parametrize("shape", [(3, 4), (1 << 18, 2)])  # below and above FRESH_MIN
def test_a_fresh_array_is_zeroed_writable_and_c_contiguous(shape: tuple[int, int]) -> None:
    a = fresh(shape, np.int64)
    assert a.shape == shape and a.dtype == np.int64 and a.flags.c_contiguous
    assert a.flags.writeable and not a.any()
    a[-1, -1] = 7
    assert a.sum() == 7


_TRIMMED = """
import os
from sigma_des.events.fast.growth import trim_heap
def rss():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
blocks = [bytearray(4096) for _ in range(16_000)]  # 64 MB of heap blocks, written
pin = bytearray(4096)  # above them: freeing them cannot shrink the heap from its top
del blocks
before = rss()
print(int(trim_heap()), before - rss(), len(pin))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_trim_heap_hands_the_heap_pages_a_run_freed_back() -> None:
    # a fresh interpreter: in a test worker the blocks could fill holes earlier tests
    # left, and the pin land below them
    out = subprocess.run([sys.executable, "-c", _TRIMMED], check=True, capture_output=True,
                         text=True, timeout=60)
    trimmed, freed, pinned = out.stdout.split()
    assert trimmed == "1" and pinned == "4096"
    assert float(freed) > 32  # the freed blocks' pages, no longer resident


class _Cycle:
    """A finished run in miniature: refers to itself, holds an array."""

    def __init__(self) -> None:
        self.me = self
        self.ring = np.ones(1000)


def test_the_run_after_a_large_finished_one_collects_its_garbage_once() -> None:
    was = gc.isenabled()
    gc.disable()  # no automatic collection in between
    try:
        c = _Cycle()
        gone = weakref.ref(c)
        del c
        run_finished(COLLECT_FROM - 1)  # a short run finished: no full collection (~0.1 s)
        before_run()
        assert gone() is not None
        run_finished(COLLECT_FROM)  # a large one: the next run collects, once
        before_run()
        assert gone() is None
        c = _Cycle()
        again = weakref.ref(c)
        del c
        before_run()  # nothing finished since: no collection (the env's many scenes)
        assert again() is not None
    finally:
        if was:
            gc.enable()


_FREED_LARGE = """
import os, sys
import numpy as np
from sigma_des.events.fast.growth import before_run
def rss():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
if sys.argv[1] == "fixed":
    before_run()
big = np.ones(2 << 20)  # 16 MB: freed, by default glibc would raise its threshold to it
del big
mid = np.ones(1 << 20)  # 8 MB: from the heap with that threshold, its own mapping here
held = rss()
del mid
print(held - rss())
"""


def _freed_mb(mode: str) -> float:
    """Resident MB handed back on freeing the 8 MB block, in a fresh interpreter: a
    large request is served from the heap whenever a free chunk fits, so a test
    worker's heap history (what earlier tests freed) would decide it, not the rule."""
    out = subprocess.run([sys.executable, "-c", _FREED_LARGE, mode], check=True,
                         capture_output=True, text=True, timeout=60)
    return float(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_after_before_run_a_freed_large_array_leaves_no_resident_pages() -> None:
    assert _freed_mb("fixed") > 6  # unmapped at once, not kept in the heap
    assert _freed_mb("default") < 1  # glibc's own rule keeps it: the check can fail


def test_a_run_refilling_a_retired_ones_arrays_does_not_trim_the_heap(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from sigma_des.events.fast import growth

    trims: list[int] = []
    monkeypatch.setattr(growth, "trim_heap", lambda: trims.append(1) or True)
    before_run(trim=False)
    assert trims == []
    before_run()
    assert trims == [1]
    with growth.trims_batched():
        before_run(trim=False)
        before_run(trim=False)
    assert trims == [1]  # nothing owed at the block's end
    with growth.trims_batched():
        before_run(trim=False)
        before_run()
    assert trims == [1, 1]  # one trim, at the block's end
