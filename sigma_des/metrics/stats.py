"""Summary statistics of metric samples (docs/concepts/metrics.md)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["SUMMARY_KEYS", "summarize"]

#: Keys of :func:`summarize`'s result, in report order.
SUMMARY_KEYS: tuple[str, ...] = ("mean", "std", "p50", "p95", "p99", "max", "count")


def summarize(x: ArrayLike) -> dict[str, float]:
    """Mean, population std, percentiles, max and count of a sample.

    Args:
        x: the samples (any shape; flattened).

    Returns:
        ``{"mean", "std" (ddof=0), "p50", "p95", "p99" (numpy 'linear' method),
        "max", "count"}``; an empty sample gives NaN for all but ``count = 0``.
    """
    a = np.asarray(x, dtype=np.float64).ravel()
    if a.size == 0:
        out = {k: float("nan") for k in SUMMARY_KEYS}
        out["count"] = 0
        return out
    p50, p95, p99 = np.percentile(a, [50.0, 95.0, 99.0], method="linear")
    return {
        "mean": float(a.mean()),
        "std": float(a.std(ddof=0)),
        "p50": float(p50),
        "p95": float(p95),
        "p99": float(p99),
        "max": float(a.max()),
        "count": int(a.size),
    }
