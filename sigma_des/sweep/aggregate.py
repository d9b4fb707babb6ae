"""Tidy per-run rows and their aggregation over seeds (mean, std, n, 95 % CI).

For each group (grid point, method, metric) over its ``n`` seeds with finite-or-
infinite (non-NaN) values ``x_1..x_n``:

* ``mean = Σx / n``;
* ``std`` = sample standard deviation ``sqrt(Σ(x − mean)² / (n − 1))``;
* ``ci95`` = half-width of the 95 % confidence interval of the mean,
  ``t_{0.975, n−1} · std / √n`` (Student's t quantile);

``std`` and ``ci95`` are NaN when ``n < 2``; NaN values (a metric undefined for
that run) are left out of ``n``.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import IO, Any

__all__ = ["AGG_COLUMNS", "aggregate_rows", "cell", "csv_writer", "t975", "write_csv"]

#: Statistic columns of an aggregate row (after the group columns).
AGG_COLUMNS: tuple[str, ...] = ("n", "mean", "std", "ci95")


@cache
def t975(df: int) -> float:
    """Student's t quantile ``t_{0.975, df}`` (df ≥ 1)."""
    if df < 1:
        raise ValueError(f"degrees of freedom must be >= 1, got {df}")
    from scipy.stats import t

    return float(t.ppf(0.975, df))


def _stats(values: Sequence[float]) -> dict[str, float | int]:
    xs = [float(v) for v in values if not (isinstance(v, float) and math.isnan(v))]
    n = len(xs)
    if n == 0:
        return {"n": 0, "mean": math.nan, "std": math.nan, "ci95": math.nan}
    mean = math.fsum(xs) / n
    if n < 2 or not math.isfinite(mean):
        return {"n": n, "mean": mean, "std": math.nan, "ci95": math.nan}
    std = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    return {"n": n, "mean": mean, "std": std, "ci95": t975(n - 1) * std / math.sqrt(n)}


def cell(v: Any) -> Any:
    """A grid value as one hashable CSV cell (lists and tables as JSON text)."""
    if isinstance(v, list | tuple | dict):
        return json.dumps(v, sort_keys=True, separators=(",", ":"))
    return v


def aggregate_rows(
    rows: Iterable[Mapping[str, Any]],
    by: Sequence[str],
    value: str = "value",
    carry: Sequence[str] = ("unit",),
) -> list[dict[str, Any]]:
    """Group ``rows`` by the columns ``by`` and summarise column ``value``.

    Args:
        rows: tidy rows (one value each).
        by: group columns, e.g. the grid keys + ``config_hash``, ``method``, ``metric``.
        value: the column to summarise.
        carry: further columns copied from the group's first row (e.g. ``unit``).

    Returns:
        One row per group, in order of first appearance: the ``by`` columns, the
        ``carry`` columns, then ``n``, ``mean``, ``std`` and ``ci95``.
    """
    groups: dict[tuple[Any, ...], list[float]] = {}
    first: dict[tuple[Any, ...], Mapping[str, Any]] = {}
    for r in rows:
        k = tuple(cell(r.get(c)) for c in by)
        if k not in groups:
            groups[k] = []
            first[k] = r
        groups[k].append(r[value])
    out: list[dict[str, Any]] = []
    for k, vals in groups.items():
        row: dict[str, Any] = dict(zip(by, k, strict=True))
        for c in carry:
            row[c] = first[k].get(c, "")
        row.update(_stats(vals))
        out.append(row)
    return out


def csv_writer(
    rows: Iterable[Mapping[str, Any]], columns: Sequence[str]
) -> Callable[[IO[str]], None]:
    """A writer of ``rows`` as CSV in the given column order (lists/tables as JSON)."""

    def write(fh: IO[str]) -> None:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: cell(r.get(c, "")) for c in columns})

    return write


def write_csv(rows: Iterable[Mapping[str, Any]], path: str | Path, columns: Sequence[str]) -> Path:
    """Write ``rows`` as CSV with the given column order (lists/tables as JSON)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open("w", newline="") as fh:
        csv_writer(rows, columns)(fh)
    return p
