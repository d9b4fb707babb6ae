"""The streamed summary of a spilled store against numpy's summary of the whole store."""

from __future__ import annotations

import numpy as np
import pytest

import sigma_des.metrics.streamed as streamed
from sigma_des.metrics.samples import Samples
from sigma_des.metrics.stats import summarize
from sigma_des.metrics.streamed import store_mean_max, summarize_store


def _store(x: np.ndarray, spill: int, parts: int = 7) -> Samples:
    s = Samples(spill=spill)
    for p in np.array_split(x, parts):
        s.extend(p)
    return s


def _assert_same(store: Samples) -> None:
    got, ref = summarize_store(store), summarize(store.values())
    assert list(got) == list(ref)
    for k in ref:  # bit for bit
        a, b = np.float64(got[k]), np.float64(ref[k])
        assert np.array_equal(a, b, equal_nan=True) and np.signbit(a) == np.signbit(b), (k, a, b)
    mean, mx = store_mean_max(store)
    assert np.array_equal([mean, mx], [ref["mean"], ref["max"]], equal_nan=True)


def test_hand_computed_store() -> None:
    s = _store(np.array([4.0, 1.0, 3.0, 2.0, 5.0]), spill=1, parts=5)
    assert s.spilled
    out = summarize_store(s)
    # mean 3, population std sqrt(2); percentiles at (n - 1) q = 2, 3.8, 3.96
    assert out["mean"] == 3.0 and out["std"] == np.sqrt(2.0)
    assert out["p50"] == 3.0 and out["max"] == 5.0 and out["count"] == 5
    assert out["p95"] == pytest.approx(4.8) and out["p99"] == pytest.approx(4.96)


def test_large_store_default_chunks() -> None:
    """A store past two chunks: the pairwise recursion crosses reads, the order
    statistics need a histogram and a read of one bin."""
    rng = np.random.default_rng(27)
    x = rng.lognormal(-4.0, 1.0, size=600_011)
    s = _store(x, spill=1 << 15)
    assert s.spilled and len(s) > 2 * streamed.CHUNK
    _assert_same(s)


@pytest.mark.parametrize("kind", ["normal", "ties", "narrow", "equal", "signed_zero", "two"])
def test_small_chunks_and_bins(kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Tiny chunks and bins force deep recursion, repeated narrowing and the split of a
    range of adjacent doubles; every figure must still be numpy's."""
    monkeypatch.setattr(streamed, "CHUNK", 128)  # the least: numpy sums 128 unsplit
    monkeypatch.setattr(streamed, "BINS", 4)
    rng = np.random.default_rng(hash(kind) % 1000)
    for n in (129, 200, 1_001, 5_003):
        if kind == "normal":
            x = rng.normal(3.0, 2.0, size=n)
        elif kind == "ties":
            x = rng.integers(0, 6, size=n).astype(np.float64) * 0.1
        elif kind == "narrow":  # a range of five adjacent doubles
            x = 1.0 + rng.integers(0, 5, size=n) * np.spacing(1.0)
        elif kind == "equal":
            x = np.full(n, 0.25)
        elif kind == "signed_zero":
            x = rng.choice([-0.0, 0.0, 1e-300], size=n)
        else:  # two adjacent doubles, many of each
            x = np.where(rng.random(n) < 0.7, 2.0, np.nextafter(2.0, 3.0))
        _assert_same(_store(x, spill=16))


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_nan_and_inf_are_summarised_whole() -> None:
    x = np.linspace(0.0, 1.0, 3_000)
    for bad in (np.nan, np.inf):
        y = x.copy()
        y[1_234] = bad
        _assert_same(_store(y, spill=64))


def test_unspilled_and_empty_stores() -> None:
    s = _store(np.arange(10.0), spill=1_000)
    assert not s.spilled
    _assert_same(s)
    e = Samples()
    assert summarize_store(e)["count"] == 0
    assert np.isnan(store_mean_max(e)).all()


def test_read_ranges_across_the_file_and_memory() -> None:
    x = np.arange(1_000.0)
    s = _store(x, spill=64)
    assert s.spilled
    for start, count in ((0, 10), (100, 500), (990, 50), (-5, 3), (2_000, 4)):
        lo = max(0, min(start, 1_000))
        np.testing.assert_array_equal(s.read(start, count), x[lo : lo + count])
