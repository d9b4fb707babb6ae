"""Hybrid logical clocks: send/receive rules case by case, monotonicity, and the
stability buffer's release order and liveness (against a heap reference too)."""

from __future__ import annotations

import heapq
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sigma_des.events.align.hlc_clock import HLC, StabilityBuffer, Stamp


class _Items:
    """The buffer with labelled items, one state per call (a batch of one)."""

    def __init__(self, n: int) -> None:
        self.buf = StabilityBuffer(n, 1)
        self.items: list[object] = []

    def add(self, node: int, stamp: Stamp, item: object) -> None:
        j = len(self.items)
        self.items.append(item)
        self.buf.add(np.array([node]), np.array([stamp.l]), np.array([stamp.c]),
                     np.array([j]), np.array([0.0]), np.zeros((1, 1)))

    def release(self) -> list[tuple[Stamp, int, object]]:
        r = self.buf.release()
        return [(Stamp(float(l_), int(c)), int(nd), self.items[int(f)])
                for l_, c, nd, f in zip(r.l, r.c, r.nodes, r.frames, strict=True)]

    def set_live(self, node: int, live: bool) -> None:
        self.buf.set_live(node, live)

    def bound(self) -> Stamp | None:
        return self.buf.bound()

    @property
    def peak(self) -> int:
        return self.buf.peak

    def __len__(self) -> int:
        return len(self.buf)


class _HeapReference:
    """A naive reference: every stamped item in a heap keyed (l, c, node, arrival)."""

    def __init__(self, n: int) -> None:
        self.live = [True] * n
        self.newest: list[tuple[float, int] | None] = [None] * n
        self.heap: list[tuple[float, int, int, int]] = []
        self.seq = 0

    def add(self, node: int, stamp: Stamp, item: int) -> None:
        key = (stamp.l, stamp.c)
        cur = self.newest[node]
        if cur is None or key > cur:
            self.newest[node] = key
        heapq.heappush(self.heap, (stamp.l, stamp.c, node, item))
        self.seq += 1

    def bound(self) -> Stamp | None:
        keys = [k for k, live in zip(self.newest, self.live, strict=True) if live]
        if not any(self.live):
            sent = [k for k in self.newest if k is not None]
            return Stamp(*max(sent)) if sent else None
        if any(k is None for k in keys):
            return None
        return Stamp(*min(k for k in keys if k is not None))

    def release(self) -> list[tuple[int, int]]:
        b = self.bound()
        out: list[tuple[int, int]] = []
        while b is not None and self.heap and (self.heap[0][0], self.heap[0][1]) <= (b.l, b.c):
            e = heapq.heappop(self.heap)
            out.append((e[2], e[3]))
        return out


def _clock(l: float, c: int) -> HLC:  # noqa: E741
    h = HLC()
    h.l, h.c = l, c
    return h


def test_initial_clock_takes_first_physical_time() -> None:
    h = HLC()
    assert h.stamp == Stamp(-math.inf, 0)
    assert h.send(-0.25) == Stamp(-0.25, 0)  # negative local time is fine


def test_send_rules() -> None:
    h = HLC()
    assert h.send(5.0) == Stamp(5.0, 0)  # pt ahead: l = pt, c = 0
    assert h.send(5.0) == Stamp(5.0, 1)  # same pt: c + 1
    assert h.send(4.0) == Stamp(5.0, 2)  # pt behind (clock stepped back): c + 1
    assert h.send(6.0) == Stamp(6.0, 0)


def test_receive_all_three_equal_takes_max_counter() -> None:
    assert _clock(10.0, 3).receive(5.0, Stamp(10.0, 7)) == Stamp(10.0, 8)
    assert _clock(10.0, 9).receive(5.0, Stamp(10.0, 7)) == Stamp(10.0, 10)


def test_receive_own_l_wins() -> None:
    assert _clock(10.0, 3).receive(5.0, Stamp(9.0, 50)) == Stamp(10.0, 4)
    assert _clock(10.0, 3).receive(10.0, Stamp(9.0, 50)) == Stamp(10.0, 4)  # pt == l'


def test_receive_message_l_wins() -> None:
    assert _clock(10.0, 3).receive(5.0, Stamp(12.0, 6)) == Stamp(12.0, 7)
    assert _clock(10.0, 3).receive(12.0, Stamp(12.0, 6)) == Stamp(12.0, 7)  # pt == m.l


def test_receive_physical_time_wins() -> None:
    h = _clock(10.0, 3)
    assert h.receive(15.0, Stamp(12.0, 6)) == Stamp(15.0, 0)
    assert (h.l, h.c) == (15.0, 0)


_times = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)
_ops = st.lists(
    st.one_of(
        st.tuples(st.just("send"), _times),
        st.tuples(st.just("recv"), _times, _times, st.integers(0, 5)),
    ),
    min_size=1,
    max_size=60,
)


@given(_ops)
def test_stamps_strictly_increase_and_dominate(ops: list[tuple]) -> None:
    h = HLC()
    prev = h.stamp
    max_pt = -math.inf
    for op in ops:
        if op[0] == "send":
            s = h.send(op[1])
            max_pt = max(max_pt, op[1])
        else:
            m = Stamp(op[2], op[3])
            s = h.receive(op[1], m)
            assert s > m
            max_pt = max(max_pt, op[1])
        assert s > prev
        assert s.l >= max_pt
        prev = s


def test_release_order_and_ties() -> None:
    buf = _Items(3)
    buf.add(0, Stamp(1.0, 0), "a")
    buf.add(1, Stamp(2.0, 0), "b")
    assert buf.bound() is None  # node 2 has sent nothing
    assert buf.release() == []
    buf.add(2, Stamp(1.5, 0), "c")
    assert buf.bound() == Stamp(1.0, 0)
    assert buf.release() == [(Stamp(1.0, 0), 0, "a")]
    buf.add(0, Stamp(2.0, 0), "d")
    assert buf.release() == [(Stamp(1.5, 0), 2, "c")]
    buf.add(2, Stamp(2.0, 0), "e")
    assert len(buf) == 3
    assert buf.release() == [
        (Stamp(2.0, 0), 0, "d"),
        (Stamp(2.0, 0), 1, "b"),
        (Stamp(2.0, 0), 2, "e"),
    ]
    assert len(buf) == 0
    assert buf.peak == 3


def test_counter_orders_equal_l() -> None:
    buf = _Items(2)
    buf.add(1, Stamp(3.0, 2), "late")
    buf.add(0, Stamp(3.0, 1), "early")
    buf.add(0, Stamp(3.0, 2), "x")
    assert buf.bound() == Stamp(3.0, 2)
    assert [item for _, _, item in buf.release()] == ["early", "x", "late"]


def test_bound_ignores_older_stamps() -> None:
    buf = _Items(2)
    buf.add(0, Stamp(5.0, 0), "new")
    buf.add(0, Stamp(4.0, 0), "old")  # e.g. a retransmission arriving late
    buf.add(1, Stamp(6.0, 0), "z")
    assert buf.bound() == Stamp(5.0, 0)
    assert [item for _, _, item in buf.release()] == ["old", "new"]


def test_dead_node_no_longer_blocks() -> None:
    buf = _Items(3)
    for node in range(3):
        buf.add(node, Stamp(1.0, 0), node)
    buf.release()
    buf.add(0, Stamp(2.0, 0), "a2")
    buf.add(1, Stamp(2.5, 0), "b2")
    assert buf.release() == []  # node 2 stuck at 1.0
    buf.set_live(2, False)
    assert buf.bound() == Stamp(2.0, 0)
    assert buf.release() == [(Stamp(2.0, 0), 0, "a2")]
    buf.set_live(2, True)
    assert buf.bound() == Stamp(1.0, 0)


def test_node_that_never_sent_blocks_until_dead() -> None:
    buf = _Items(2)
    buf.add(0, Stamp(1.0, 0), "a")
    assert buf.release() == []
    buf.set_live(1, False)
    assert buf.release() == [(Stamp(1.0, 0), 0, "a")]


def test_no_live_node_releases_everything() -> None:
    buf = _Items(2)
    assert buf.bound() is None
    buf.add(0, Stamp(1.0, 4), "a")
    buf.add(1, Stamp(1.0, 7), "b")
    buf.add(1, Stamp(0.5, 0), "c")
    buf.set_live(0, False)
    buf.set_live(1, False)
    assert buf.bound() == Stamp(1.0, 7)
    assert [item for _, _, item in buf.release()] == ["c", "a", "b"]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.lists(
            st.tuples(
                st.integers(0, 3),
                st.sampled_from([0.0, 0.5, 1.0, 1.5]),
                st.integers(0, 2),
            ),
            max_size=6,
        ),
        min_size=1,
        max_size=6,
    ),
    st.lists(st.integers(0, 3), max_size=3),
)
def test_batch_buffer_releases_what_the_heap_buffer_releases(
    batches: list[list[tuple[int, float, int]]], dead: list[int]
) -> None:
    """Same bound, same released set, same order (HLC order, node, arrival)."""
    heap, batch = _HeapReference(4), StabilityBuffer(4, 1)
    for node in dead:
        heap.live[node] = False
        batch.set_live(node, False)
    seq = 0
    for rows in batches:
        for node, l_, c in rows:
            heap.add(node, Stamp(l_, c), seq)
            seq += 1
        if rows:
            nodes = np.array([r[0] for r in rows], dtype=np.int64)
            ls = np.array([r[1] for r in rows])
            cs = np.array([r[2] for r in rows], dtype=np.int64)
            ids = np.arange(seq - len(rows), seq, dtype=np.int64)
            batch.add(nodes, ls, cs, ids, ids.astype(float), ids[:, None].astype(float))
        assert heap.bound() == batch.bound()
        want = heap.release()
        rel = batch.release()
        got_nodes, got_ids = rel.nodes, rel.frames
        assert list(zip(got_nodes.tolist(), got_ids.tolist(), strict=True)) == want
        assert len(heap.heap) == len(batch)
