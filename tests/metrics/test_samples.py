"""Samples, the 8-byte-a-sample store, against the lists and concatenations it replaced."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sigma_des.metrics.fidelity import TrajectoryLog, formation_error
from sigma_des.metrics.samples import Samples
from sigma_des.metrics.stats import summarize

finite = st.floats(-1e6, 1e6, allow_nan=False, width=64)
chunks = st.lists(st.lists(finite, max_size=40), max_size=30)


@settings(max_examples=60, deadline=None)
@given(chunks, st.lists(finite, max_size=20))
def test_summary_of_samples_equals_summary_of_the_concatenation(
    parts: list[list[float]], singles: list[float]
) -> None:
    s = Samples()
    whole: list[float] = []
    for p in parts:
        s.extend(np.array(p, dtype=np.float64))
        whole.extend(p)
    for v in singles:
        s.append(v)
        whole.append(v)
    assert len(s) == len(whole) and s.nbytes == 8 * len(whole)
    got, ref = summarize(s.values()), summarize(np.asarray(whole))
    assert got.keys() == ref.keys()
    for k in ref:  # bit for bit (NaN for an empty sample)
        assert np.array_equal(np.float64(got[k]), np.float64(ref[k]), equal_nan=True), k


def test_a_view_never_changes_when_more_values_come() -> None:
    s = Samples()
    s.extend(np.arange(3.0))
    v = s.values()
    s.append(7.0)  # the view is alive: the store continues in a copy
    s.extend(np.array([[8.0, 9.0]]))
    assert v.tolist() == [0.0, 1.0, 2.0]
    assert s.values().tolist() == [0.0, 1.0, 2.0, 7.0, 8.0, 9.0]
    assert not s.values().flags.writeable


def test_large_sample_is_8_bytes_a_value() -> None:
    s = Samples()
    for _ in range(100):
        s.extend(np.ones(1000))
    assert s.nbytes == 800_000 and s.values().sum() == 100_000.0


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 700), st.integers(1, 40), st.integers(1, 300), st.integers(0, 2**31))
def test_blocked_formation_error_equals_the_whole_array_formula(
    t: int, n: int, block: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(t, n, 3)) * 50.0
    b = a + rng.normal(size=(t, n, 3))
    shape_a = a - a.mean(axis=1, keepdims=True)
    shape_b = b - b.mean(axis=1, keepdims=True)
    ref = np.linalg.norm(shape_a - shape_b, axis=2).mean(axis=1)
    assert np.array_equal(formation_error(a, b, block), ref)


def test_trajectory_log_equals_the_stacked_interpolation() -> None:
    rng = np.random.default_rng(3)
    p0 = rng.normal(size=(4, 3))
    log = TrajectoryLog(30.0, p0)
    ref = [p0.copy()]
    prev_t, prev = 0.0, p0.copy()
    j = 1
    for k in range(1, 50):
        t, pos = k * 0.01, rng.normal(size=(4, 3))
        log.add(t, pos)
        while j / 30.0 <= t + 1e-12:
            w = (j / 30.0 - prev_t) / (t - prev_t)
            ref.append((1.0 - w) * prev + w * pos)
            j += 1
        prev_t, prev = t, pos.copy()
    times, got = log.arrays()
    assert got.shape == (len(ref), 4, 3) == (len(times), 4, 3)
    assert np.array_equal(got, np.stack(ref))
    log.add(0.6, np.zeros((4, 3)))  # logging on after arrays() leaves them as they were
    assert np.array_equal(got, np.stack(ref)) and log.arrays()[1].shape[0] > len(ref)


@settings(max_examples=60, deadline=None)
@given(chunks, st.integers(1, 9))
def test_spilled_samples_read_back_the_same_values_in_order(
    parts: list[list[float]], spill: int
) -> None:
    s = Samples(spill=spill)
    whole: list[float] = []
    for i, p in enumerate(parts):
        if i % 3 == 2 and p:
            s.append(p[0])
            whole.append(p[0])
        else:
            s.extend(np.array(p, dtype=np.float64))
            whole.extend(p)
        assert s.resident_bytes < 16 * spill
    got = s.values()
    assert len(s) == len(whole) == got.size and s.nbytes == 8 * len(whole)
    assert got.tobytes() == np.asarray(whole, dtype=np.float64).tobytes()
    assert not got.flags.writeable


def test_a_spilled_store_keeps_one_chunk_to_two_in_memory() -> None:
    s = Samples(spill=4)
    s.extend(np.arange(7.0))  # under two chunks: all in memory
    assert s.resident_bytes == 56
    s.append(7.0)  # 8 = two chunks: one goes to disk
    assert s.resident_bytes == 32 and len(s) == 8
    first = s.values()
    s.extend(np.arange(8.0, 19.0))  # 19 values: 4 + 12 on disk, 7 (1 chunk + 3) kept
    assert s.resident_bytes == 56
    assert first.tolist() == list(range(8)) and s.values().tolist() == list(range(19))
    assert Samples(spill=None).resident_bytes == 0
