"""Compiled per-tick pieces of the collector: the render sample and the AoI update.

Each kernel does the floating-point operations of the numpy code it replaces, in the
same order (``tests/metrics/test_tick_kernels.py`` checks them bit for bit against that
code on random cases): element-wise arithmetic is the same IEEE operation either way,
``np.linalg.norm`` of a row of three is ``sqrt((e0² + e1²) + e2²)``, and a numpy sum or
mean of a contiguous array is numpy's pairwise summation added to the identity 0.0
(:func:`sigma_des.metrics.streamed.pairwise_sum`). Imported on first use: the scenario's
modules import no numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.metrics.streamed import pairwise_sum

__all__ = ["aoi_apply", "changed_states", "render_sample"]


@njit(cache=True)
def aoi_apply(t: float, nodes: np.ndarray, g: np.ndarray, gen: np.ndarray, acc: np.ndarray,
              start: np.ndarray, area: np.ndarray, t_start: float,
              peaks: np.ndarray) -> tuple[int, float]:
    """``AoITracker.update``'s vector path for distinct ``nodes``: apply the newer states
    ``g``; the AoI peaks ``t - old gen`` of the nodes already shown go to ``peaks`` in the
    order of ``nodes``. Returns their number and ``np.sum`` of them (numpy's pairwise
    sum added to the identity 0.0; 0.0 when there is none); ``(-1 - j, 0.0)``, having
    changed nothing, when ``nodes[j]`` is out of range."""
    n = gen.shape[0]
    for idx in range(nodes.shape[0]):  # numpy's indexing: negative ids wrap, others raise
        if not -n <= nodes[idx] < n:
            return -1 - idx, 0.0
    k = 0
    for idx in range(nodes.shape[0]):
        i = nodes[idx] if nodes[idx] >= 0 else nodes[idx] + n
        gi = g[idx]
        old = gen[i]
        if old == old:  # shown: close the sawtooth piece [acc, t]
            if not gi > old:
                continue
            a = acc[i]
            dt = t - a
            if not dt >= 0.0 and dt == dt:  # np.maximum(t - a, 0.0): NaN stays NaN
                dt = 0.0
            area[i] += dt * ((t + a) * 0.5 - old)
            if a == a and not a >= t:  # np.maximum(a, t)
                acc[i] = t
            peaks[k] = t - old
            k += 1
        else:
            if gi != gi:
                continue
            begin = max(t, t_start)
            acc[i] = begin
            start[i] = begin
        gen[i] = gi
    return k, (0.0 + pairwise_sum(peaks, 0, k)) if k else 0.0


@njit(cache=True)
def changed_states(gen: np.ndarray, shown: np.ndarray, nodes: np.ndarray,
                   gens: np.ndarray) -> int:
    """The nodes (in order) whose ``gen`` is a state (not NaN) other than ``shown``'s,
    and their ``gen``, into ``nodes`` and ``gens``; returns their number."""
    k = 0
    for i in range(gen.shape[0]):
        g = gen[i]
        if g == g and not g == shown[i]:
            nodes[k] = i
            gens[k] = g
            k += 1
    return k


@njit(cache=True)
def render_sample(t: float, gen: np.ndarray, frame: np.ndarray, obs: np.ndarray,
                  flag: np.ndarray, truth: np.ndarray, ref: int, filled: int,
                  extrapolated: int, ages: np.ndarray, errs: np.ndarray
                  ) -> tuple[int, int, int, int, int, int, float, float]:
    """One render tick of ``Collector.render`` over the nodes with a state (``gen`` not
    NaN): their ages ``t - gen`` into ``ages``, their position errors against ``truth``
    (``(n, 3)``; none when it has no rows; NaN errors left out) into ``errs``.

    Returns ``(ages, errors, frame spread, filled, extrapolated, off the reference
    frame, mean age, maximum age)``: counts of nodes (``ages`` is also the number shown;
    ``filled`` and ``extrapolated`` over every row of ``flag``), the mean as numpy's, both
    NaN when no node has a state.
    """
    n = gen.shape[0]
    k = 0
    m = 0
    fmin = 0
    fmax = 0
    off = 0
    has_truth = truth.shape[0] > 0
    for i in range(n):
        g = gen[i]
        if g != g:
            continue
        ages[k] = t - g
        f = frame[i]
        if k == 0 or f < fmin:
            fmin = f
        if k == 0 or f > fmax:
            fmax = f
        if ref >= 0 and f != ref:
            off += 1
        k += 1
        if has_truth:
            e0 = obs[i, 9] - truth[i, 0]
            e1 = obs[i, 10] - truth[i, 1]
            e2 = obs[i, 11] - truth[i, 2]
            e = math.sqrt((e0 * e0 + e1 * e1) + e2 * e2)
            if e == e:
                errs[m] = e
                m += 1
    nf = 0
    ne = 0
    for i in range(flag.shape[0]):
        if flag[i] == filled:
            nf += 1
        if flag[i] == extrapolated:
            ne += 1
    mean = math.nan
    hi = math.nan
    if k:
        mean = (0.0 + pairwise_sum(ages, 0, k)) / k
        hi = ages[0]
        for j in range(1, k):  # np.max (no NaN among the ages: gen is not NaN)
            if ages[j] > hi:
                hi = ages[j]
    return k, m, fmax - fmin, nf, ne, off, mean, hi
