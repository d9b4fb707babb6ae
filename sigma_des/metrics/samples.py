"""Growing stores of float64 samples, 8 bytes a sample (docs/MODEL.md, "Metrics").

A run's collector keeps samples it needs whole at the end (exact percentiles, and
numpy's pairwise-summed mean over the whole sample, which no incremental sum
reproduces bit for bit): delivery latencies, AoI ages at render ticks, position
errors, the fidelity trajectory log. A Python list of floats costs 32 bytes a sample
(a pointer and a float object) and a list of per-tick arrays about 100 bytes of
overhead per array plus a full copy when concatenated at the end; a :class:`Samples`
holds the values contiguously in an ``array('d')`` (grown by ``realloc``, a few per
cent over-allocation) and hands them out as one float64 array without copying.
"""

from __future__ import annotations

from array import array

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Samples"]


class Samples:
    """An append-only sequence of float64 values.

    :meth:`values` is a read-only view of the values so far. Appending while such a
    view is alive copies the store first (the view keeps the old values), so views
    never change and never dangle.
    """

    __slots__ = ("_a",)

    def __init__(self) -> None:
        self._a = array("d")

    def __len__(self) -> int:
        return len(self._a)

    @property
    def nbytes(self) -> int:
        """Bytes of the values held (8 per sample; the store over-allocates a few %)."""
        return len(self._a) * 8

    def append(self, value: float) -> None:
        """Add one value."""
        try:
            self._a.append(value)
        except BufferError:  # a values() view is alive: continue in a copy
            self._a = array("d", self._a)
            self._a.append(value)

    def extend(self, values: ArrayLike) -> None:
        """Add every value of ``values`` (any shape, flattened in C order)."""
        raw = np.ascontiguousarray(values, dtype=np.float64).reshape(-1).view(np.uint8).data
        try:
            self._a.frombytes(raw)
        except BufferError:  # a values() view is alive: continue in a copy
            self._a = array("d", self._a)
            self._a.frombytes(raw)

    def values(self) -> NDArray[np.float64]:
        """The values so far, in order, as a read-only float64 array (no copy)."""
        v = np.frombuffer(self._a, dtype=np.float64)
        v.flags.writeable = False
        return v
