"""Grid specification: parse ``--grid``/``--seeds`` text, expand points, build scenarios.

A grid is either a mapping ``{dotted key: [values]}`` (its Cartesian product, the
first key varying slowest) or an explicit list of points (``[{"nodes": 10,
"hosts": 1}, ...]``) for keys that must move together. Every point is applied to
a base :class:`~sigma_des.config.Scenario` and validated up front, so a typo or an
out-of-range value fails before any work with a :class:`~sigma_des.errors.ConfigError`
naming the key.
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from sigma_des.config import (
    ALL_METHODS,
    METHODS,
    Scenario,
    parse_set,
    set_key,
    to_dict,
)
from sigma_des.errors import ConfigError
from sigma_des.loading import from_dict
from sigma_des.overrides import split_item

__all__ = [
    "Grid",
    "apply_point",
    "expand_grid",
    "format_point",
    "grid_keys",
    "parse_grid_args",
    "parse_methods",
    "parse_seeds",
    "split_values",
    "validate_points",
]

#: A grid: a mapping of dotted keys to value lists, or an explicit list of points.
Grid = Mapping[str, Sequence[Any]] | Sequence[Mapping[str, Any]]

#: Keys a grid may not vary: they have their own arguments (``seeds``, ``methods``).
RESERVED_KEYS: tuple[str, ...] = ("seed", "methods")

_CLOSE = {"[": "]", "{": "}"}


def split_values(raw: str) -> list[str]:
    """Split ``raw`` at top-level commas (not inside ``[]``, ``{}`` or quotes).

    >>> split_values("1, [2, 3], {a = 1, b = 2}, 'x,y'")
    ['1', '[2, 3]', '{a = 1, b = 2}', "'x,y'"]
    """
    parts: list[str] = []
    stack: list[str] = []
    quote: str | None = None
    cur: list[str] = []
    for ch in raw:
        if quote is not None:
            cur.append(ch)
            if ch == quote:
                quote = None
            continue
        if ch in "'\"":
            quote = ch
        elif ch in _CLOSE:
            stack.append(_CLOSE[ch])
        elif stack and ch == stack[-1]:
            stack.pop()
        elif ch == "," and not stack:
            parts.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur).strip())
    return parts


def parse_grid_args(items: Iterable[str]) -> dict[str, list[Any]]:
    """Parse repeatable ``key=v1,v2,...`` items; each value is read as TOML like ``--set``.

    Raises:
        ConfigError: malformed item, empty value, or a key given twice.
    """
    grid: dict[str, list[Any]] = {}
    for item in items:
        key, raw = split_item(item, "a grid axis must look like key=v1,v2,...", "--grid")
        if key in grid:
            raise ConfigError(key, "given twice in --grid; list all its values in one --grid")
        pieces = split_values(raw)
        if any(p == "" for p in pieces):
            raise ConfigError(key, f"empty value in --grid {item!r}")
        grid[key] = [parse_set(f"{key}={p}")[1] for p in pieces]
    return grid


_RANGE = re.compile(r"^\s*(\d+)\s*\.\.\s*(\d+)\s*$")


#: Most seeds one sweep may run (each is a run per point and method).
MAX_SEEDS = 100_000


def _seed_range(first: int, last: int) -> range:
    """Seeds ``first..last``, refused before it is built if there are too many."""
    if last - first + 1 > MAX_SEEDS:
        raise ConfigError(
            "seeds", f"at most {MAX_SEEDS} seeds per sweep, got {first}..{last} "
            f"({last - first + 1})"
        )
    return range(first, last + 1)


def parse_seeds(text: str | int | Sequence[int]) -> list[int]:
    """Seeds from ``"5"`` (= 1..5), ``"1,2,3"``, ``"3..7"`` (inclusive) or a list.

    Raises:
        ConfigError: (key ``seeds``) not integers, negative, empty or repeated.
    """
    seeds: list[int]
    if isinstance(text, bool):
        raise ConfigError("seeds", f"must be a count or a list of integers, got {text!r}")
    if isinstance(text, int):
        seeds = list(_seed_range(1, text))
    elif isinstance(text, str):
        s = text.strip()
        m = _RANGE.match(s)
        try:
            if m:
                seeds = list(_seed_range(int(m.group(1)), int(m.group(2))))
            elif "," in s:
                seeds = [int(x) for x in s.split(",") if x.strip()]
            else:
                seeds = list(_seed_range(1, int(s)))
        except ConfigError:
            raise
        except ValueError:
            raise ConfigError(
                "seeds", f"must be N (= 1..N), a..b or a comma list of integers, got {text!r}"
            ) from None
    else:
        seeds = list(text)
    if not seeds:
        raise ConfigError("seeds", f"names no seed: {text!r}")
    if len(seeds) > MAX_SEEDS:
        raise ConfigError("seeds", f"at most {MAX_SEEDS} seeds per sweep, got {len(seeds)}")
    for s_ in seeds:
        if isinstance(s_, bool) or not isinstance(s_, int) or not 0 <= s_ < 2**63:
            raise ConfigError("seeds", f"every seed must be an integer in 0..2^63-1, got {s_!r}")
    if len(set(seeds)) != len(seeds):
        raise ConfigError("seeds", f"lists a seed twice: {seeds}")
    return seeds


def parse_methods(methods: str | Iterable[str]) -> list[str]:
    """Methods from ``"none,bides"`` or a list; validated against ``METHODS``.

    Raises:
        ConfigError: (key ``methods``) unknown, empty or repeated method.
    """
    ms = [m.strip() for m in methods.split(",")] if isinstance(methods, str) else list(methods)
    ms = [m for m in ms if m]
    if not ms:
        raise ConfigError("methods", f"must name at least one of {', '.join(METHODS)}")
    for m in ms:
        if m not in ALL_METHODS:
            raise ConfigError("methods", f"unknown method {m!r}; allowed: {', '.join(ALL_METHODS)}")
    if len(set(ms)) != len(ms):
        raise ConfigError("methods", f"lists a method twice: {ms}")
    return ms


def expand_grid(grid: Grid) -> list[dict[str, Any]]:
    """The grid's points, in order (Cartesian product; the first key varies slowest).

    An empty mapping gives one empty point (the base scenario alone).

    Raises:
        ConfigError: an axis without values, a reserved key, or a malformed point.
    """
    if isinstance(grid, Mapping):
        for k, vs in grid.items():
            _check_key(k)
            if isinstance(vs, str | bytes) or not isinstance(vs, Sequence):
                raise ConfigError(k, f"grid values must be a list, got {vs!r}")
            if len(vs) == 0:
                raise ConfigError(k, "grid axis has no values")
        keys = list(grid)
        return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]
    points: list[dict[str, Any]] = []
    for i, p in enumerate(grid):
        if not isinstance(p, Mapping):
            raise ConfigError(f"grid[{i}]", f"a grid point must be a table, got {p!r}")
        for k in p:
            _check_key(k)
        points.append(dict(p))
    if not points:
        raise ConfigError("grid", "the list of grid points is empty")
    return points


def grid_keys(points: Sequence[Mapping[str, Any]]) -> list[str]:
    """All keys of the points, in order of first appearance."""
    keys: dict[str, None] = {}
    for p in points:
        keys.update(dict.fromkeys(p))
    return list(keys)


def _check_key(key: str) -> None:
    if not isinstance(key, str) or not key:
        raise ConfigError(str(key), "a grid key must be a non-empty dotted string")
    if key in RESERVED_KEYS:
        arg, param = ("--seeds", "seeds") if key == "seed" else ("--methods", "methods")
        raise ConfigError(key, f"cannot be a grid axis; use {arg} (Sweep(..., {param}=...))")


def format_point(point: Mapping[str, Any]) -> str:
    """``key=value`` text of a point, e.g. ``nodes=10 hosts=1``."""
    if not point:
        return "(base)"
    return " ".join(f"{k}={json.dumps(v, default=str)}" for k, v in point.items())


def apply_point(base: Scenario, point: Mapping[str, Any]) -> Scenario:
    """``base`` with the point's dotted keys set, validated.

    Raises:
        ConfigError: unknown key, wrong type or out-of-range value, naming the key.
    """
    # automatic hosts and warmup are derived anew from the point's nodes and duration
    data = to_dict(base, keep_auto=True)
    for key, value in point.items():
        set_key(data, key, value)
    return from_dict(Scenario, data)  # type: ignore[no-any-return]


def validate_points(base: Scenario, points: Sequence[Mapping[str, Any]]) -> list[Scenario]:
    """Build every point's scenario; the first invalid one raises.

    Raises:
        ConfigError: naming the offending key, with the grid point in the reason.
    """
    out: list[Scenario] = []
    for p in points:
        try:
            out.append(apply_point(base, p))
        except ConfigError as e:
            raise ConfigError(e.key, f"{e.reason} (at grid point {format_point(p)})") from None
    return out
