"""The run-merge event queue gives exactly the ``(time, sequence)`` order."""

from __future__ import annotations

import heapq
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sigma_des.events.fast.driver as driver
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.primitives import push
from sigma_des.events.fast.queue import peek, take
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.fast.test_layout import DIMS  # the layout's dimensions, one place
from tests.events.test_cohort import run_both


def _state(cap: int, arena: int) -> tuple[Any, ...]:
    dims = {**DIMS, "cap": cap, "arena": arena}
    given = {
        f.name: np.zeros(L.shape_of(f, dims), dtype=f.dtype)
        for f in L.FIELDS
        if f.fill is None
    }
    return L.allocate(dims, given)


def _pop(S: tuple[Any, ...]) -> tuple[float, int] | None:
    t = peek(S)
    if not S[L.Q_INT][CO.QI_HAS]:
        return None
    return float(t), int(take(S))


def _run(S: tuple[Any, ...], batches: list[list[float]], pops: list[int]) -> list[int]:
    """Push each batch (slot = push order), pop ``pops[i]`` events after batch i, drain.

    Returns:
        The sequence numbers in the order they came out (slot = sequence here).
    """
    out: list[int] = []
    seq = 0
    for batch, k in zip(batches, pops, strict=True):
        for t in batch:
            push(S, t, seq)
            seq += 1
        for _ in range(k):
            got = _pop(S)
            if got is None:
                break
            out.append(got[1])
    while (got := _pop(S)) is not None:
        out.append(got[1])
    return out


def _spec(batches: list[list[float]], pops: list[int]) -> tuple[list[int], int]:
    """The specification: one heap of all events, keyed (t, sequence).

    Returns:
        The order, and the most events queued at once.
    """
    heap: list[tuple[float, int]] = []
    out: list[int] = []
    seq = peak = 0
    for batch, k in zip(batches, pops, strict=True):
        for t in batch:
            heapq.heappush(heap, (t, seq))
            seq += 1
        peak = max(peak, len(heap))
        for _ in range(min(k, len(heap))):
            out.append(heapq.heappop(heap)[1])
    out.extend(heapq.heappop(heap)[1] for _ in range(len(heap)))
    return out, peak


def _expected(batches: list[list[float]], pops: list[int]) -> list[int]:
    return _spec(batches, pops)[0]


def test_ties_in_time_come_out_in_creation_order() -> None:
    S = _state(16, 16)
    # one batch: a broadcast whose deliveries are not sorted, with ties in t
    assert _run(S, [[3.0, 1.0, 2.0, 1.0, 3.0, 0.5]], [0]) == [5, 1, 3, 2, 0, 4]


def test_pending_minimum_is_sealed_before_the_current_run() -> None:
    S = _state(16, 16)
    # the first run (1, 2, 4) is being consumed when an event at 3 is pushed: it must
    # come out between 2 and 4; one at exactly 4 comes after the older event at 4
    assert _run(S, [[1.0, 2.0, 4.0], [3.0, 4.0]], [1, 1]) == [0, 1, 3, 2, 4]
    assert S[L.Q_INT][CO.QI_HEAP] == 0 and S[L.Q_INT][CO.QI_PN] == 0


def test_runs_stay_out_of_the_heap_until_they_interleave() -> None:
    S = _state(16, 16)
    for i, t in enumerate([1.0, 2.0, 3.0]):
        push(S, t, i)
    assert _pop(S) == (1.0, 0)
    qi = S[L.Q_INT]
    assert qi[CO.QI_HEAP] == 0 and qi[CO.QI_NRUN] == 1  # one run, consumed in place
    push(S, 5.0, 3)  # later than the current run's next: stays pending
    assert _pop(S) == (2.0, 1) and qi[CO.QI_PN] == 1
    push(S, 2.5, 4)  # earliest now: sealed with 5.0 into a second run
    assert _pop(S) == (2.5, 4) and qi[CO.QI_NRUN] == 2 and qi[CO.QI_HEAP] == 1
    assert [_pop(S), _pop(S), _pop(S)] == [(3.0, 2), (5.0, 3), None]


def test_a_full_arena_is_compacted_in_place() -> None:
    S = _state(4, 6)
    out = _run(S, [[5.0, 1.0, 2.0], [0.5], [3.0, 0.7], [4.0], [0.9, 6.0]], [2, 1, 1, 1, 0])
    assert out == _expected([[5.0, 1.0, 2.0], [0.5], [3.0, 0.7], [4.0], [0.9, 6.0]],
                            [2, 1, 1, 1, 0])
    assert S[L.Q_INT][CO.QI_ATOP] <= 6


times = st.sampled_from([0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.lists(times, max_size=9), st.integers(0, 6)), max_size=12))
def test_random_pushes_come_out_in_time_sequence_order(
    steps: list[tuple[list[float], int]]
) -> None:
    batches = [b for b, _ in steps]
    pops = [k for _, k in steps]
    order, peak = _spec(batches, pops)
    # the tightest capacities the queue supports (the events queued at once, plus one
    # sealing boundary): the arena is compacted as often as it can be
    S = _state(max(peak, 1), max(peak, 1) + 1)
    assert _run(S, batches, pops) == order


@pytest.mark.parametrize("arena", [8, 9, 40])
def test_every_arena_size_gives_the_same_order(arena: int) -> None:
    rng = np.random.default_rng(arena)
    batches = [list(np.round(rng.uniform(0, 4, 3), 1)) for _ in range(10)]
    pops = [2, 4] * 5
    S = _state(8, arena)
    assert _run(S, batches, pops) == _expected(batches, pops)


def test_a_run_with_the_smallest_arena_compacts_grows_and_stays_identical(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Arena = event table, no slack: compaction and growth on every path, same results."""
    monkeypatch.setattr(driver, "SLACK", 0)
    monkeypatch.setattr(driver, "ARENA", 1)
    # a broker slower than its load: the backlog grows the table (from 28 to 490 slots)
    sc = tiny(nodes=6, **{"broker.delivery_service": 0.002, "commands.enabled": True})
    run_both(sc, "bides")
    run = MethodRun(replace(sc, engine="cohort").run_spec(), "none", make_dynamics(sc),
                    make_behaviour(sc), compiled=True)
    assert isinstance(run.core, driver.CompiledCore)
    cap0 = run.core.array("run_t").size
    assert cap0 == run.core.array("ev_int").shape[0] == 4 * 7
    sizes: list[tuple[int, int]] = []
    run.run(lambda t: sizes.append((run.core.array("run_t").size,
                                    run.core.array("ev_int").shape[0])))
    assert sizes[-1][0] == sizes[-1][1] > cap0
