"""The aligners' shared pieces: a batch of one, the newest-row rule, the registry."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.errors import ConfigError
from sigma_des.events.align import ALIGNERS, make_aligner
from sigma_des.events.align.base import OneState, StateBatch, one_state, take_newest
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.align.spec import AlignParams, LockstepSpec


class _Ctx:
    latest_trigger = 0
    f_trig = 100.0

    def __init__(self) -> None:
        self.timers: list[float] = []
        self.barriers: list[int] = []

    def now(self) -> float:
        return 0.0

    def call_at(self, t: float, fn: object, *args: object) -> None:
        self.timers.append(t)

    def set_rate(self, f_trig: float) -> None:
        self.f_trig = f_trig

    def barrier_done(self, frame: int) -> None:
        self.barriers.append(frame)

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        pass


def test_one_state_is_a_batch_of_one() -> None:
    b = one_state(1.5, 3, 7, 1.25, np.arange(12.0), Stamp(1.0, 4))
    assert [a.shape for a in b] == [(1,), (1,), (1,), (1,), (1, 12), (1,), (1,)]
    assert (b.t[0], b.nodes[0], b.frames[0], b.gens[0], b.hlc_l[0], b.hlc_c[0]) == (
        1.5, 3, 7, 1.25, 1.0, 4)
    assert b.obs[0, 11] == 11.0
    assert np.isnan(one_state(0.0, 0, 0, 0.0, np.zeros(12)).hlc_l[0])


def _rows(nodes: list[int], frames: list[int]) -> StateBatch:
    m = len(nodes)
    return StateBatch(np.zeros(m), np.array(nodes), np.array(frames), np.arange(m) + 0.5,
                      np.arange(m, dtype=float)[:, None] * np.ones((1, 2)), np.zeros(m),
                      np.zeros(m, dtype=np.int64))


def test_take_newest_batch_equals_rows_one_by_one() -> None:
    nodes, frames = [0, 1, 0, 2, 1, 0], [3, 1, 5, 0, 1, 5]
    f, g, o = np.array([4, -1, 2]), np.full(3, np.nan), np.full((3, 2), np.nan)
    changed = take_newest(f, g, o, _rows(nodes, frames))
    # node 0: the first row of its highest frame (5, row 2) beats 4; node 1: row 1 (frame
    # 1 beats -1, the later frame-1 row does not replace it); node 2: frame 0 < 2, kept
    assert sorted(changed.tolist()) == [0, 1]
    assert f.tolist() == [5, 1, 2] and g[:2].tolist() == [2.5, 1.5] and np.isnan(g[2])
    f1, g1, o1 = np.array([4, -1, 2]), np.full(3, np.nan), np.full((3, 2), np.nan)
    for j in range(len(nodes)):
        take_newest(f1, g1, o1, _rows([nodes[j]], [frames[j]])._replace(
            gens=np.array([j + 0.5]), obs=np.full((1, 2), float(j))))
    assert f1.tolist() == f.tolist()
    np.testing.assert_array_equal(g1, g)
    np.testing.assert_array_equal(o1, o)


def test_registry_builds_every_method_from_its_params() -> None:
    params = AlignParams(lockstep=LockstepSpec(retry_timeout=0.25))
    for name in ("none", "lockstep", "hlc", "bides", "rpc"):
        al = make_aligner(name, 4, _Ctx(), params)
        assert al.name == name and type(al) is ALIGNERS[name]
    ctx = _Ctx()
    ls = make_aligner("lockstep", 2, ctx, params)
    ls.on_trigger(0, 1.0)
    assert ctx.timers == [1.25]  # its own spec's retry timeout
    with pytest.raises(ConfigError, match="net.middleware = 'mqtt'"):
        make_aligner("rpc", 2, _Ctx(), AlignParams(middleware="dds"))


def test_lockstep_report_counts_rerequests_and_evictions() -> None:
    ctx = _Ctx()
    ls = make_aligner("lockstep", 3, ctx, AlignParams(lockstep=LockstepSpec(eviction_timeout=1.0)))
    ls.on_trigger(0, 0.0)
    ls.on_states(one_state(0.01, 0, 0, 0.0, np.zeros(12)))
    ls.align(0.02)
    rep = ls.report()
    assert (rep.evicted, rep.rejoined, rep.rerequests) == (0, 0, 0)
    assert rep.peak_bytes == 2 * 3 * (12 * 8 + 16)
    assert make_aligner("none", 3, ctx, AlignParams()).report().evicted == 0


def test_reusable_batch_of_one_equals_one_state_and_is_overwritten() -> None:
    one = OneState(width=3)
    a = one.fill(0.5, 7, 12, 0.25, np.array([1.0, 2.0, 3.0]), Stamp(0.4, 2))
    ref = one_state(0.5, 7, 12, 0.25, np.array([1.0, 2.0, 3.0]), Stamp(0.4, 2))
    for got, want in zip(a, ref, strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
    b = one.fill(0.75, 3, 13, 0.5, np.array([4.0, 5.0, 6.0]))
    assert b is a  # the same arrays, overwritten: no allocation per state
    assert a.nodes.tolist() == [3] and a.frames.tolist() == [13] and a.t.tolist() == [0.75]
    assert np.isnan(a.hlc_l[0]) and a.hlc_c[0] == 0 and a.obs.tolist() == [[4.0, 5.0, 6.0]]


def test_take_newest_equals_the_sorted_rule_on_drawn_batches() -> None:
    """The compiled pass gives :func:`newest_rows`' entries and changed nodes (the former
    sorted implementation), on drawn batches with repeated frames, obs given as a
    strided view (a compiled core's delivery buffer)."""
    from sigma_des.events.align.base import newest_rows

    rng = np.random.default_rng(3)
    for _ in range(300):
        n, m = int(rng.integers(1, 7)), int(rng.integers(2, 12))
        nodes = rng.integers(0, n, m)
        frames = rng.integers(-1, 6, m)
        buf = rng.normal(size=(m, 16))
        batch = StateBatch(np.zeros(m), nodes, frames, rng.normal(size=m), buf[:, 3:15],
                           np.zeros(m), np.zeros(m, dtype=np.int64))
        f0 = rng.integers(-1, 5, n)
        g0, o0 = rng.normal(size=n), rng.normal(size=(n, 12))
        f, g, o = f0.copy(), g0.copy(), o0.copy()
        got = take_newest(f, g, o, batch)
        win = newest_rows(nodes, frames, f0)  # the reference
        nd = nodes[win]
        f0[nd], g0[nd], o0[nd] = frames[win], batch.gens[win], batch.obs[win]
        assert got.tolist() == sorted(nd.tolist())
        assert f.tolist() == f0.tolist() and g.tobytes() == g0.tobytes()
        assert o.tobytes() == o0.tobytes()
