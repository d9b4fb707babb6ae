"""core/rng.py's mix: the compiled path and the numpy path give the SplitMix64 bits.

The reference below is the hash written out in Python integers modulo 2**64 (the
module's definition: each id ``i`` absorbed as ``fin(h ^ ((i + 1) * golden))``, then one
more ``fin``), independent of numpy and numba.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from sigma_des.core.rng import RandomStreams, Stream, _key_of, mix, mix_int

MASK = (1 << 64) - 1


def _fin(z: int) -> int:
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def _ref(key: int, *ids: int) -> int:
    h = key
    for i in ids:
        h = _fin(h ^ (((i + 1) * 0x9E3779B97F4A7C15) & MASK))
    return _fin(h)


I64 = (-(1 << 63), (1 << 63) - 1)


@pytest.mark.parametrize("size", [0, 1, 7, 40])
@pytest.mark.parametrize("where", [0, 1, 3])  # the array first, second, last of four ids
def test_mix_of_scalars_around_one_array_is_splitmix64(size: int, where: int) -> None:
    rng = np.random.default_rng(size * 10 + where)
    for _ in range(20):
        key = int(rng.integers(0, 1 << 63)) * 2 + 1
        col = rng.integers(*I64, size=size, endpoint=True)
        if size:
            col[0] = I64[0]  # the extremes and -1 (whose id + 1 wraps to 0)
        if size > 2:
            col[1], col[2] = I64[1], -1
        scalars = [int(x) for x in rng.integers(*I64, size=3, endpoint=True)]
        ids: list[object] = list(scalars)
        ids.insert(where, col)
        got = mix(np.uint64(key), *ids)
        assert got.dtype == np.uint64 and got.shape == (size,)
        for j in range(size):
            row = list(scalars)
            row.insert(where, int(col[j]))
            assert int(got[j]) == _ref(key, *row)


def test_other_shapes_and_dtypes_hash_the_same_way() -> None:
    key = 0x0123456789ABCDEF
    grid = mix(key, np.arange(3)[:, None], np.arange(20, dtype=np.int32)[None, :], 5)
    assert grid.shape == (3, 20)
    assert all(int(grid[a, b]) == _ref(key, a, b, 5) for a in range(3) for b in range(20))
    assert [int(x) for x in mix(key, np.arange(12, dtype=np.int16), np.int64(4))] == [
        _ref(key, b, 4) for b in range(12)]
    assert int(mix(key, 3, 4)[0]) == _ref(key, 3, 4) and int(mix(key)[0]) == _ref(key)


def test_stream_uniform_is_the_top_53_bits_of_the_hash() -> None:
    s = Stream(3, "latency")
    u = s.uniform(2, np.arange(50), 9, 0)
    h = [_ref(int(s.key), 2, b, 9, 0) for b in range(50)]
    assert u.tolist() == [((x >> 11) + 0.5) / 2.0**53 for x in h]


@pytest.mark.parametrize("order", ["row_first", "col_first"])
@pytest.mark.parametrize("shape", [(1, 1), (4, 7), (0, 3), (5, 0), (1, 16), (6, 1)])
def test_mix_of_a_row_and_a_column_among_scalars_is_splitmix64(order: str,
                                                               shape: tuple[int, int]) -> None:
    # the draw blocks' key: (kind, subjects (1, n), indices (m, 1), attempt), and
    # (kind, subjects, index, attempts (m, 1)); the compiled outer path
    m, n = shape
    rng = np.random.default_rng(m * 10 + n)
    key = int(rng.integers(0, 1 << 63)) * 2 + 1
    row = rng.integers(*I64, size=n, endpoint=True)
    col = rng.integers(*I64, size=m, endpoint=True)
    if n:
        row[0] = -1
    if m:
        col[0] = I64[1]
    a, b, c = (int(x) for x in rng.integers(*I64, size=3, endpoint=True))
    if order == "row_first":
        got = mix(np.uint64(key), a, row[None, :], b, col[:, None], c)
        want = [[_ref(key, a, int(row[j]), b, int(col[i]), c) for j in range(n)]
                for i in range(m)]
    else:
        got = mix(np.uint64(key), a, col[:, None], row[None, :], c)
        want = [[_ref(key, a, int(col[i]), int(row[j]), c) for j in range(n)] for i in range(m)]
    assert got.dtype == np.uint64 and got.shape == (m, n)
    assert [[int(x) for x in r] for r in got] == want


def test_mix_int_is_mix_of_scalars() -> None:
    rng = np.random.default_rng(5)
    for n_ids in range(6):
        for _ in range(50):
            key = int(rng.integers(0, 1 << 63)) * 2 + 1
            ids = [int(x) for x in rng.integers(*I64, size=n_ids, endpoint=True)]
            assert mix_int(key, *ids) == int(mix(np.uint64(key), *ids)[0]) == _ref(key, *ids)
    for ids in ([I64[0], -1, I64[1]], [2**63 + 5, 3], [2**64 - 1]):  # uint64-range ids wrap
        assert mix_int(99, *ids) == int(mix(99, *ids)[0])


def test_a_streams_key_is_the_blake2b_of_its_seed_and_name() -> None:
    """RandomStreams hashes a name on from the seed's part of the hash: the key of
    ``Stream(seed, name)``, which hashes ``f"{seed}\\x00{name}"`` whole."""
    import hashlib

    for seed in (0, 1, 77, 2**62, 2**63 - 1):
        streams = RandomStreams(seed)
        for name in ("clocks", "lat.host.up", "env.tight", "", "né"):
            got = streams.stream(name)
            want = hashlib.blake2b(f"{seed}\x00{name}".encode(), digest_size=8).digest()
            assert got.key == _key_of(seed, name) == Stream(seed, name).key
            assert int(got.key) == int.from_bytes(want, "little")
            assert type(got.key) is np.uint64 and got.name == name
            assert streams.stream(name) is got  # cached
    assert RandomStreams(1).stream("a").key != RandomStreams(2).stream("a").key


def test_random_streams_pickle_as_their_seed() -> None:
    streams = RandomStreams(9)
    back = pickle.loads(pickle.dumps(streams))
    assert back.seed == 9 and back.stream("x").key == streams.stream("x").key
