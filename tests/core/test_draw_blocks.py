"""Draws of consecutive indices in one sampler call (DrawCache.block, DrawBlock): each row
is the per-index vector's bits, for every sampler the compiled core's tables read."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.draws import BLOCK, BLOCK_VALUES, DrawBlock, DrawCache
from sigma_des.core.rng import RandomStreams
from sigma_des.events.jobs import step_draws
from sigma_des.events.spec import ComputeSpec
from sigma_des.net.latency import Dist
from sigma_des.net.links import dist_cache

DISTS = [Dist(dist="normal", mean=0.2, std=0.04), Dist(dist="lognormal", mean=0.0008, std=0.0002),
         Dist(dist="exponential", mean=0.01), Dist(dist="uniform", low=0.001, high=0.003)]


@pytest.mark.parametrize("seed", [1, 77, 2**40 + 3])
@pytest.mark.parametrize("dist", DISTS, ids=[d.dist for d in DISTS])
def test_block_rows_are_the_vectors_bits(seed: int, dist: Dist) -> None:
    cache = dist_cache(7, dist, RandomStreams(seed), "lat.host.up")
    assert cache.blockable
    block = cache.block(2, np.arange(123, 143), 0)
    assert block.shape == (20, 7)
    for j in range(20):
        np.testing.assert_array_equal(block[j], cache.vector(2, 123 + j, 0))
    assert len(np.unique(block)) == block.size  # real draws, not one row repeated


@pytest.mark.parametrize("rho", [0.0, 0.5])
def test_draw_block_serves_rows_in_and_out_of_its_block(rho: float) -> None:
    compute = ComputeSpec(host_share=rho)
    cache = step_draws(compute, RandomStreams(5), [0, 0, 1, 1, 1])
    assert cache.blockable == (rho == 0.0)  # the host copula's sampler takes one index
    b = DrawBlock(cache, 3)
    assert b.rows == BLOCK  # 5 subjects: the most indices
    for index in [10, 11, 10 + BLOCK - 1, 10 + BLOCK, 9, 500, 10]:
        np.testing.assert_array_equal(b.row(index), cache.vector(3, index, 0))


def test_a_constant_cache_blocks_its_constant() -> None:
    cache = DrawCache(3, lambda s, k, i, a: s * 1.0, constant=0.25)
    assert cache.block(1, np.arange(4)).tolist() == [[0.25] * 3] * 4


def test_block_of_an_unblockable_cache_is_an_error() -> None:
    cache = DrawCache(3, lambda s, k, i, a: s * 1.0 + i)
    with pytest.raises(ValueError, match="one index at a time"):
        cache.block(1, np.arange(4))
    with pytest.raises(ValueError, match="1-d array"):
        cache.block(1, 3, 0)


def test_loss_uniforms_block_bitwise() -> None:
    from sigma_des.net.links import _uniform_sampler

    stream = RandomStreams(9).stream("lossu.host.up")
    cache = DrawCache(6, _uniform_sampler(stream), blockable=True)
    block = cache.block(1, np.arange(BLOCK))
    for j in range(BLOCK):
        np.testing.assert_array_equal(block[j], cache.vector(1, j, 0))


@pytest.mark.parametrize("dist", DISTS[:2], ids=[d.dist for d in DISTS[:2]])
def test_block_over_attempts_is_the_vectors_bits(dist: Dist) -> None:
    # the rollback draws' key: (kind, node, target, j), j the attempt axis
    cache = step_draws(ComputeSpec(step_time=dist), RandomStreams(3), [0, 0, 0, 1])
    block = cache.block(4, 250, np.arange(2, 11))
    assert block.shape == (9, 4)
    for j in range(9):
        np.testing.assert_array_equal(block[j], cache.vector(4, 250, 2 + j))


def test_large_swarms_draw_fewer_indices_per_block() -> None:
    cache = DrawCache(1000, lambda s, k, i, a: s * 1.0 + i, blockable=True)
    assert DrawBlock(cache, 0).rows == BLOCK_VALUES // 1000
    assert DrawBlock(DrawCache(10**5, lambda s, k, i, a: s * 1.0), 0).rows == 1
    b = DrawBlock(cache, 0, rows=3)
    assert b.row(7)[:2].tolist() == [7.0, 8.0] and b.values.shape == (3, 1000)


def test_compiled_uniform_rows_are_the_streams_bits() -> None:
    from sigma_des.core.counter_rng import uniform_rows

    st = RandomStreams(2**62 + 9).stream("lossu.host.up")
    subj = np.array([0, 3, -1, 2**62, -(2**63)], dtype=np.int64)
    idx = np.array([7, -5, 2**63 - 1], dtype=np.int64)
    got = uniform_rows(st.key, np.int64(4), subj, idx, np.array([2], dtype=np.int64))
    assert got.tobytes() == st.uniform(4, subj[None, :], idx[:, None], 2).tobytes()
    att = np.arange(-2, 4, dtype=np.int64)
    got = uniform_rows(st.key, np.int64(-3), subj, np.array([11], dtype=np.int64), att)
    assert got.tobytes() == st.uniform(-3, subj[None, :], 11, att[:, None]).tobytes()


@pytest.mark.parametrize("empirical", [False, True])
def test_blocks_of_the_links_loss_and_compute_caches_take_the_compiled_uniforms(
        tmp_path: object, empirical: bool) -> None:
    from pathlib import Path

    from sigma_des.net.links import _uniform_sampler

    streams = RandomStreams(21)
    dist = Dist(dist="exponential", mean=0.01)
    if empirical:
        f = Path(str(tmp_path)) / "d.txt"
        f.write_text("0.1\n0.25\n0.05\n0.3\n")
        dist = Dist(dist="empirical", file=str(f))
    caches = [dist_cache(6, dist, streams, "lat.host.down"),
              step_draws(ComputeSpec(step_time=Dist(dist="lognormal", mean=1e-3, std=4e-4)),
                         streams, [0, 0, 1, 1, 2, 2]),
              DrawCache(6, _uniform_sampler(streams.stream("lossu.host.up")), blockable=True,
                        uniforms=(streams.stream("lossu.host.up").key, None))]
    for cache in caches:
        assert cache.uniforms is not None
        by_index = cache.block(2, np.arange(300, 340), 1)
        for j in range(40):
            assert by_index[j].tobytes() == cache.vector(2, 300 + j, 1).tobytes()
        by_attempt = cache.block(1, 77, np.arange(0, 9))
        for j in range(9):
            assert by_attempt[j].tobytes() == cache.vector(1, 77, j).tobytes()
        assert len(np.unique(by_index)) > (3 if empirical and cache is caches[0] else 200)
