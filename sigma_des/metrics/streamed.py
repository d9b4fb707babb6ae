"""Exact summaries of a spilled sample store in bounded memory (docs/concepts/metrics.md).

:func:`~sigma_des.metrics.stats.summarize` of ``store.values()`` reads a spilled
:class:`~sigma_des.metrics.samples.Samples` store back whole, and numpy then makes
full-size temporaries of it (``percentile``'s copy, ``std``'s deviations): at the end
of a run, about twice its largest store, which grows with the simulated duration
(docs/concepts/metrics.md). :func:`summarize_store` gives the same
numbers, bit for bit, reading at most :data:`CHUNK` values at a time:

* the sum is numpy's pairwise summation (``add.reduce`` of a contiguous float64 array,
  numpy 2: blocks of up to 128 values summed with eight accumulators, longer ranges
  split in two at half the length rounded down to a multiple of 8, the whole added to
  the identity 0.0) replayed over the store: a range of at most CHUNK values is read
  and summed in memory, where the recursion goes on unchanged. The mean is that sum
  over ``n`` (``np.mean``); ``std`` (``ddof = 0``) the square root of the same sum of
  the squared deviations from the mean, over ``n`` (``np.std``), in a second pass;
* the maximum is the running one;
* each percentile (numpy's ``linear`` method) needs the two order statistics around
  its virtual index ``(n - 1) q``: a histogram of :data:`BINS` bins over the values'
  range keeps the bin that holds the wanted rank, and again within that bin, until the
  bin holds at most CHUNK values, which are read and partitioned; numpy's
  interpolation between the two is reproduced as numpy writes it.

A store that never spilled, or that holds NaN or infinite values, is summarised whole,
as before. ``tests/metrics/test_streamed.py`` checks every figure against
:func:`~sigma_des.metrics.stats.summarize` of the whole store.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sigma_des.metrics.samples import Samples
from sigma_des.metrics.stats import SUMMARY_KEYS, summarize

__all__ = ["BINS", "CHUNK", "pairwise_sum", "store_mean_max", "summarize_store"]

#: Values read from a store at a time (1 MB); at least 128, numpy's unsplit block, so
#: that every range read is a node of numpy's own recursion.
CHUNK = 1 << 17
#: Bins of each histogram that narrows an order statistic's range.
BINS = 4096
#: The percentiles :func:`~sigma_des.metrics.stats.summarize` reports.
PERCENTILES = (50.0, 95.0, 99.0)


@njit(cache=True)
def _block(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's ``pairwise_sum`` of ``a[lo : lo + n]`` for ``n <= 128`` (no split)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - (n % 8):
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def _half(n: int) -> int:
    """Where numpy splits a range of ``n > 128`` values: half, down to a multiple of 8."""
    n2 = n // 2
    return n2 - n2 % 8


@njit(cache=True)
def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's ``pairwise_sum`` of ``a[lo : lo + n]`` (the same additions, in order).

    numpy's recursion (a range of more than 128 values is the sum of its two halves,
    :func:`_half`; a shorter one a :func:`_block`) run on an explicit stack: a compiled
    function that calls itself cannot be called from another compiled function that
    numba loads from its cache (the recursive symbol is left unresolved)."""
    if n <= 128:
        return _block(a, lo, n)
    depth = 2  # a part of m values has at most m // 2 + 8 (both halves): a bound
    m = n
    while m > 128:
        m = m // 2 + 8
        depth += 1
    start = np.empty(depth, dtype=np.int64)
    size = np.empty(depth, dtype=np.int64)
    left = np.empty(depth)
    right_next = np.zeros(depth, dtype=np.bool_)  # the left half is summed: now the right
    sp = 0
    start[0], size[0] = lo, n
    while True:
        if size[sp] > 128:  # descend into the left half
            start[sp + 1], size[sp + 1] = start[sp], _half(size[sp])
            right_next[sp + 1] = False
            sp += 1
            continue
        ret = _block(a, start[sp], size[sp])
        sp -= 1
        while sp >= 0 and right_next[sp]:  # both halves done: add them, return upwards
            ret = left[sp] + ret
            sp -= 1
        if sp < 0:
            return ret
        left[sp] = ret  # the left half of sp is done: sum its right half
        right_next[sp] = True
        h = _half(size[sp])
        start[sp + 1], size[sp + 1] = start[sp] + h, size[sp] - h
        right_next[sp + 1] = False
        sp += 1


def _key(v: float) -> int:
    """The double's place in the order of doubles, as an unsigned 64-bit integer
    (positive: the bits with the top one set; negative: the bits inverted)."""
    u = int(np.float64(v).view(np.uint64))
    return (~u & (1 << 64) - 1) if u >> 63 else u | 1 << 63


@njit(cache=True)
def _histogram(x: np.ndarray, lo: np.uint64, width: np.uint64, counts: np.ndarray) -> None:
    """Add the values of ``x`` whose key lies in ``[lo, lo + width * counts.size)`` to
    ``counts``: bin ``b`` holds the keys ``lo + b * width`` to ``lo + (b + 1) * width - 1``."""
    keys = x.view(np.uint64)
    top = np.uint64(1 << 63)
    for u in keys:
        k = ~u if u & top else u | top
        if k < lo:
            continue
        b = (k - lo) // width
        if b < counts.size:
            counts[b] += 1


@njit(cache=True)
def _collect(x: np.ndarray, lo: np.uint64, hi: np.uint64, out: np.ndarray, n: int) -> int:
    """Copy the values of ``x`` whose key lies in ``[lo, hi]`` to ``out[n:]``; the new ``n``."""
    keys = x.view(np.uint64)
    top = np.uint64(1 << 63)
    for i in range(keys.size):
        u = keys[i]
        k = ~u if u & top else u | top
        if lo <= k <= hi:
            out[n] = x[i]
            n += 1
    return n


def _chunks(store: Samples) -> list[tuple[int, int]]:
    n = len(store)
    return [(s, min(CHUNK, n - s)) for s in range(0, n, CHUNK)]


def _sum(
    store: Samples, lo: int, n: int, mean: float | None = None,
    seen: Callable[[NDArray[np.float64]], None] | None = None,
) -> float:
    """The pairwise sum of values ``lo .. lo + n`` (of their squared deviations from
    ``mean`` if given), each range of at most CHUNK values read once and shown to
    ``seen``."""
    if n <= CHUNK:
        x = store.read(lo, n)
        if seen is not None:
            seen(x)
        if mean is not None:
            x -= mean  # numpy's std: arr - arrmean, then squared in place
            x *= x
        return float(pairwise_sum(x, 0, n))
    n2 = n // 2
    n2 -= n2 % 8
    return _sum(store, lo, n2, mean, seen) + _sum(store, lo + n2, n - n2, mean, seen)


class _Rank:
    """The search for the value of rank ``r`` (0-based): its key lies in ``[lo, hi]``,
    with ``below`` values of smaller keys and ``inside`` values within."""

    def __init__(self, r: int, lo: int, hi: int, n: int) -> None:
        self.r, self.lo, self.hi, self.below, self.inside = r, lo, hi, 0, n

    @property
    def done(self) -> bool:
        return self.lo == self.hi

    @property
    def width(self) -> int:
        """Keys per bin of the next histogram (at least one)."""
        return -(-(self.hi - self.lo + 1) // BINS)

    def narrow(self, counts: NDArray[np.int64]) -> None:
        """Keep the bin that holds the rank (``counts`` of the last histogram)."""
        cum = np.cumsum(counts)
        b = int(np.searchsorted(cum, self.r - self.below, side="right"))
        self.below += int(cum[b - 1]) if b else 0
        self.inside = int(counts[b])
        w = self.width
        self.lo, self.hi = self.lo + b * w, min(self.hi, self.lo + (b + 1) * w - 1)


def _value(key: int) -> float:
    """The double of an order key (the inverse of :func:`_key`)."""
    bits = key ^ 1 << 63 if key >> 63 else ~key & (1 << 64) - 1
    return float(np.uint64(bits).view(np.float64))


def _order_stats(store: Samples, ranks: list[int], lo: float, hi: float) -> dict[int, float]:
    """The values of the given ranks (0-based, ascending order) of a finite store:
    histograms over the keys narrow each rank's range :data:`BINS`-fold a pass (at
    most 6 passes for 2^64 keys), until it is one key or holds at most CHUNK values."""
    todo = [_Rank(r, _key(lo), _key(hi), len(store)) for r in sorted(set(ranks))]
    while live := [k for k in todo if not k.done and k.inside > CHUNK]:
        ranges = {(k.lo, k.hi) for k in live}
        counts = {rg: np.zeros(BINS, dtype=np.int64) for rg in ranges}
        widths = {rg: np.uint64(-(-(rg[1] - rg[0] + 1) // BINS)) for rg in ranges}
        for s, c in _chunks(store):
            x = store.read(s, c)
            for rg in ranges:
                _histogram(x, np.uint64(rg[0]), widths[rg], counts[rg])
        for k in live:
            k.narrow(counts[(k.lo, k.hi)])
    out = {k.r: _value(k.lo) for k in todo if k.done}
    grab = [k for k in todo if not k.done]
    if grab:
        got = [np.empty(k.inside) for k in grab]
        fill = [0] * len(grab)
        for s, c in _chunks(store):
            x = store.read(s, c)
            for i, k in enumerate(grab):
                fill[i] = _collect(x, np.uint64(k.lo), np.uint64(k.hi), got[i], fill[i])
        for i, k in enumerate(grab):
            v = got[i][: fill[i]]
            t = k.r - k.below
            v.partition(t)
            out[k.r] = float(v[t])
    return out


def _percentiles(store: Samples, lo: float, hi: float) -> list[float]:
    """numpy's ``percentile(values, PERCENTILES, method="linear")``, read in chunks."""
    n = len(store)
    q = np.true_divide(np.array(PERCENTILES), 100)
    vi = (n - 1) * q
    prev = np.floor(vi)
    nxt = prev + 1
    above = vi >= n - 1
    prev[above] = -1
    nxt[above] = -1
    ip, inx = prev.astype(np.intp), nxt.astype(np.intp)
    gamma = np.asanyarray(vi - ip, dtype=vi.dtype)
    ip[ip < 0] += n
    inx[inx < 0] += n
    val = _order_stats(store, [*ip.tolist(), *inx.tolist()], lo, hi)
    a = np.array([val[i] for i in ip.tolist()])
    b = np.array([val[i] for i in inx.tolist()])
    diff_b_a = b - a  # numpy's _lerp, as written there
    out = np.add(a, diff_b_a * gamma)
    np.subtract(b, diff_b_a * (1 - gamma), out=out, where=gamma >= 0.5)
    return [float(v) for v in out]


def _first_pass(store: Samples) -> tuple[float, float, float]:
    """(pairwise sum, min, max) of the store in one read; max is NaN if any value is,
    min if any is -0.0."""
    seen = [math.inf, -math.inf]

    def extremes(x: NDArray[np.float64]) -> None:
        seen[0] = min(seen[0], float(x.min()))
        seen[1] = float(np.maximum(seen[1], x.max()))
        if np.any((x == 0.0) & np.signbit(x)):  # -0.0: numpy's partition orders it
            seen[0] = math.nan  # as 0.0, in no order we could reproduce: whole

    total = 0.0 + _sum(store, 0, len(store), seen=extremes)
    return total, seen[0], seen[1]


def store_mean_max(store: Samples) -> tuple[float, float]:
    """``(values.mean(), values.max())`` of a store (NaN, NaN when empty), bit for bit,
    in bounded memory."""
    n = len(store)
    if n == 0:
        return math.nan, math.nan
    if not store.spilled:
        v = store.values()
        return float(v.mean()), float(v.max())
    total, _, hi = _first_pass(store)
    return total / n, hi


def summarize_store(store: Samples) -> dict[str, float]:
    """:func:`~sigma_des.metrics.stats.summarize` of the store's values, bit for bit,
    reading at most :data:`CHUNK` values at a time when it spilled to disk."""
    n = len(store)
    if not store.spilled or n == 0:
        return summarize(store.values())
    total, lo, hi = _first_pass(store)
    if not math.isfinite(hi - lo):  # NaN or inf (or a range past float64): numpy's own rules
        return summarize(store.values())
    mean = total / n
    std = math.sqrt((0.0 + _sum(store, 0, n, mean)) / n)
    p50, p95, p99 = _percentiles(store, lo, hi)
    out = {"mean": mean, "std": std, "p50": p50, "p95": p95, "p99": p99, "max": hi,
           "count": n}
    return {k: out[k] for k in SUMMARY_KEYS}
