"""Flatten an env's nested outputs (tuples, lists, dicts of arrays) for exact comparison."""

from __future__ import annotations

from typing import Any

import numpy as np


def flat_arrays(x: Any) -> list[np.ndarray]:
    """Every leaf of ``x`` as an array, dict entries in key order."""
    if isinstance(x, dict):
        return [v for k in sorted(x) for v in flat_arrays(x[k])]
    if isinstance(x, tuple | list):
        return [v for item in x for v in flat_arrays(item)]
    return [np.asarray(x)]
