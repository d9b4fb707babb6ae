"""A trigger's draw rows in one pass (FrameDraws) hold what DrawTables.fill writes kind by
kind: the same values and tags, over block boundaries, jumps back, row widths that differ,
and caches that draw one index per call."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.draws import DrawCache
from sigma_des.events.fast.codes import K_COMMAND, K_STATE, K_TRIGGER, STEP, SVC_DEL, SVC_PUB
from sigma_des.events.fast.frame_draws import FrameDraws
from sigma_des.events.fast.tables import DrawTables
from sigma_des.events.jobs import STEP_DRAW
from tests.events.fast.test_draw_tables import Counting

KINDS = (K_TRIGGER, K_STATE, 0)


def _tables(blockable: bool) -> tuple[DrawTables, Counting]:
    sampler = Counting()  # its values broadcast: a block is one call
    wide = DrawCache(3, sampler, blockable=blockable)
    narrow = DrawCache(2, sampler, blockable=blockable)
    const = DrawCache(3, sampler, constant=0.5)
    return DrawTables([(SVC_PUB, K_TRIGGER, wide), (SVC_DEL, K_TRIGGER, narrow),
                       (SVC_PUB, K_STATE, narrow), (SVC_DEL, K_STATE, const),
                       (SVC_PUB, K_COMMAND, wide), (STEP, 0, narrow)],
                      history=5, subjects=3), sampler


@pytest.mark.parametrize("blockable", [True, False])
def test_frame_draws_write_the_rows_of_drawtables_fill(blockable: bool) -> None:
    fast, sampler = _tables(blockable)
    ref, _ = _tables(blockable)
    frames = FrameDraws(fast, KINDS)
    assert frames.rows == (64 if blockable else 1)
    for k in (0, 1, 2, 3, 4, 63, 64, 65, 200, 199, 7):
        frames.fill(k)
        for kind in KINDS:
            ref.fill(kind, k)
        np.testing.assert_array_equal(fast.values, ref.values)
        np.testing.assert_array_equal(fast.tags, ref.tags)
    # by hand: frame 7 in row 2 of the trigger's wide and narrow tables and the compute
    # table (sampled with STEP_DRAW); the command's table untouched
    assert fast.values[0, 2].tolist() == [K_TRIGGER * 1e4 + 70.0, K_TRIGGER * 1e4 + 70.1,
                                          K_TRIGGER * 1e4 + 70.2]
    assert fast.values[1, 2, :2].tolist() == [K_TRIGGER * 1e4 + 70.0, K_TRIGGER * 1e4 + 70.1]
    assert fast.values[4, 2, :2].tolist() == [STEP_DRAW * 1e4 + 70.0, STEP_DRAW * 1e4 + 70.1]
    assert fast.tags[:, 2].tolist() == [7, 7, 7, -1, 7]
    assert fast.tags[3].tolist() == [-1] * 5  # K_COMMAND: not a frame's kind
    if blockable:  # one call per table and block: 0..63, 64..127, 200..263, 199.., 7..
        assert len(sampler.calls) == 4 * 5
    else:  # one vector per table and frame
        assert len(sampler.calls) == 4 * 11


def test_frame_draws_of_constant_sources_only_fill_nothing() -> None:
    sampler = Counting()
    const = DrawCache(2, sampler, constant=0.25)
    tables = DrawTables([(SVC_PUB, K_TRIGGER, const)], history=3, subjects=2)
    FrameDraws(tables, KINDS).fill(4)
    assert sampler.calls == [] and tables.tags.tolist() == [[-1, -1, -1]]


@pytest.mark.parametrize("blockable", [True, False])
def test_command_draws_write_the_rows_of_drawtables_fill(blockable: bool) -> None:
    """The core's command draws (a FrameDraws of the command kind): every other tick, as
    an env's command ticks come, the rows DrawTables.fill writes."""
    fast, _ = _tables(blockable)
    ref, _ = _tables(blockable)
    ticks = FrameDraws(fast, (K_COMMAND,))
    for k in (0, 2, 4, 62, 64, 66, 130, 128, 3):
        ticks.fill(k)
        ref.fill(K_COMMAND, k)
        np.testing.assert_array_equal(fast.values, ref.values)
        np.testing.assert_array_equal(fast.tags, ref.tags)
    assert fast.tags[3].tolist() == [130, 66, 62, 3, 64]  # the command table, row k % 5
    assert fast.tags[0].tolist() == [-1] * 5  # the trigger's: untouched


def _stream_tables(seed: int) -> DrawTables:
    """Tables of real streams (each cache ``quantile(uniform)`` of its stream, widths 6
    and 5): normal and lognormal latencies, uniform loss draws, the compute stream."""
    from sigma_des.core.rng import RandomStreams
    from sigma_des.net.latency import Dist
    from sigma_des.net.links import dist_cache

    streams = RandomStreams(seed)
    lat = dist_cache(6, Dist("normal", mean=0.2, std=0.04), streams, "lat.a")
    step = dist_cache(5, Dist("lognormal", mean=0.002, std=0.001), streams, "compute")
    u = streams.stream("lossu.a")
    loss = DrawCache(6, lambda s, k, i, a: u.uniform(k, s, i, a), blockable=True,
                     uniforms=(u.key, None))
    expo = dist_cache(6, Dist("exponential", mean=0.01), streams, "lat.b")
    return DrawTables([(SVC_PUB, K_TRIGGER, lat), (SVC_DEL, K_TRIGGER, loss),
                       (SVC_PUB, K_STATE, expo), (SVC_PUB, K_COMMAND, lat), (STEP, 0, step)],
                      history=7, subjects=6)


@pytest.mark.parametrize("seed", [1, 2])
def test_frame_draws_of_streams_in_one_call_hold_each_keys_vector(seed: int) -> None:
    """The tables' uniforms drawn in one call: every row holds the bits of its cache's
    vector of the row's key (the per-message engine's draw), block after block."""
    tables = _stream_tables(seed)
    frames = FrameDraws(tables, KINDS)
    ticks = FrameDraws(tables, (K_COMMAND,))
    assert frames._merged is not None and ticks._merged is not None
    fills = [(c, cache, kind) for k in (*KINDS, K_COMMAND) for c, cache, kind in tables.fills_of(k)]
    for k in (0, 1, 5, 63, 64, 65, 130, 129, 6):
        frames.fill(k)
        ticks.fill(k)
        row = k % 7
        for c, cache, kind in fills:
            want = cache.vector(kind, k, 0)
            assert tables.tags[c, row] == k
            assert tables.values[c, row, : want.size].tobytes() == want.tobytes(), (c, k)
