"""Validation helpers for the frozen spec dataclasses of every layer.

Each raises :class:`~sigma_des.errors.ConfigError` naming the local field; the
scenario loader prefixes the dotted path (``net.host_link.bandwidth_mbps``).
"""

from __future__ import annotations

import math
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["require", "require_in", "require_nonneg", "require_positive"]


def require(cond: bool, key: str, reason: str) -> None:
    """Raise ``ConfigError(key, reason)`` unless ``cond``."""
    if not cond:
        raise ConfigError(key, reason)


def require_positive(obj: Any, *names: str) -> None:
    """Each named field of ``obj`` must be a finite number > 0."""
    for n in names:
        v = getattr(obj, n)
        require(v > 0 and math.isfinite(v), n, f"must be a finite number > 0, got {v}")


def require_nonneg(obj: Any, *names: str) -> None:
    """Each named field of ``obj`` must be a finite number >= 0."""
    for n in names:
        v = getattr(obj, n)
        require(v >= 0 and math.isfinite(v), n, f"must be a finite number >= 0, got {v}")


def require_in(obj: Any, name: str, lo: float, hi: float, unit: str = "") -> None:
    """Field ``name`` of ``obj`` must lie in ``[lo, hi]`` (finite)."""
    v = getattr(obj, name)
    require(lo <= v <= hi, name, f"must be in [{lo:g}, {hi:g}]{unit}, got {v}")
