"""summarize(): hand-computed statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.metrics.stats import SUMMARY_KEYS, summarize


def test_hand_computed() -> None:
    s = summarize(np.array([4.0, 1.0, 3.0, 2.0]))
    assert s["mean"] == 2.5
    assert s["std"] == pytest.approx(math.sqrt(1.25), rel=1e-15)  # population (ddof=0)
    assert s["p50"] == 2.5
    assert s["p95"] == pytest.approx(3.85, rel=1e-12)  # rank 0.95 * 3 = 2.85 -> 3 + 0.85
    assert s["p99"] == pytest.approx(3.97, rel=1e-12)
    assert s["max"] == 4.0
    assert s["count"] == 4
    assert tuple(s) == SUMMARY_KEYS


def test_single_and_2d() -> None:
    s = summarize([5.0])
    assert (s["mean"], s["std"], s["p99"], s["max"], s["count"]) == (5.0, 0.0, 5.0, 5.0, 1)
    assert summarize(np.arange(6.0).reshape(2, 3))["count"] == 6


def test_empty() -> None:
    s = summarize(np.array([]))
    assert s["count"] == 0
    assert all(math.isnan(s[k]) for k in SUMMARY_KEYS if k != "count")
