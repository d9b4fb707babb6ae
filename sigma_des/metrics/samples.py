"""Growing stores of float64 samples, 8 bytes a sample (docs/concepts/metrics.md).

A run's collector keeps samples it needs whole at the end (exact percentiles, and
numpy's pairwise-summed mean over the whole sample, which no incremental sum
reproduces bit for bit): delivery latencies, AoI ages at render ticks, position
errors, the fidelity trajectory log. A Python list of floats costs 32 bytes a sample
(a pointer and a float object) and a list of per-tick arrays about 100 bytes of
overhead per array plus a full copy when concatenated at the end. A :class:`Samples`
holds the values contiguously in an ``array('d')`` (grown by ``realloc``, a few per
cent over-allocation); past ``spill`` values it streams whole chunks out to an
anonymous temporary file (already unlinked; the operating system deletes it when the
store goes), so a long run's memory stays flat while it runs, and :meth:`values`
reads them back, in order, as one float64 array when they are needed.
"""

from __future__ import annotations

import io
import tempfile
from array import array

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SPILL", "Samples"]

#: Values a store holds in memory before it streams chunks of them to disk (1 MB).
SPILL = 1 << 17


class Samples:
    """An append-only sequence of float64 values.

    Args:
        spill: values held in memory before whole chunks of ``spill`` values go to a
            temporary file (None: never; everything stays in memory).

    :meth:`values` returns a read-only array of the values so far: a view (no copy)
    while nothing was spilled, else a fresh array read back from the file. Appending
    while a view is alive copies the store first (the view keeps the old values), so
    a returned array never changes and never dangles.
    """

    __slots__ = ("_a", "_file", "_on_disk", "_spill")

    def __init__(self, spill: int | None = SPILL) -> None:
        if spill is not None and spill < 1:
            raise ValueError(f"spill must be >= 1 or None, got {spill}")
        self._a = array("d")
        self._spill = spill
        self._file: io.BufferedRandom | None = None
        self._on_disk = 0  # values in the file

    def __len__(self) -> int:
        return self._on_disk + len(self._a)

    @property
    def nbytes(self) -> int:
        """Bytes of the values held, in memory and on disk (8 per sample)."""
        return len(self) * 8

    @property
    def resident_bytes(self) -> int:
        """Bytes of the values held in memory (the rest is in the temporary file)."""
        return len(self._a) * 8

    def append(self, value: float) -> None:
        """Add one value."""
        try:
            self._a.append(value)
        except BufferError:  # a values() view is alive: continue in a copy
            self._a = array("d", self._a)
            self._a.append(value)
        if self._spill is not None and len(self._a) >= 2 * self._spill:
            self._maybe_spill()

    def extend(self, values: ArrayLike) -> None:
        """Add every value of ``values`` (any shape, flattened in C order)."""
        raw = np.ascontiguousarray(values, dtype=np.float64).reshape(-1).view(np.uint8).data
        try:
            self._a.frombytes(raw)
        except BufferError:  # a values() view is alive: continue in a copy
            self._a = array("d", self._a)
            self._a.frombytes(raw)
        self._maybe_spill()

    def _maybe_spill(self) -> None:
        """Stream whole chunks of ``spill`` values to the file, keep the rest in memory."""
        k = self._spill
        if k is None or len(self._a) < 2 * k:
            return
        keep = len(self._a) % k + k  # at least one chunk stays: appends stay cheap
        out = len(self._a) - keep
        if self._file is None:
            self._file = tempfile.TemporaryFile(prefix="sigma_des_samples.")
        with memoryview(self._a) as whole:
            self._file.write(whole[:out])
            tail = array("d")
            tail.frombytes(whole[out:].cast("B"))
        self._on_disk += out
        self._a = tail  # a new store: a values() view of the old one stays valid

    def __del__(self) -> None:
        if self._file is not None:
            self._file.close()

    @property
    def spilled(self) -> bool:
        """Whether some values are in the temporary file (:meth:`values` then reads them
        all back into a fresh array)."""
        return self._on_disk > 0

    def read(self, start: int, count: int) -> NDArray[np.float64]:
        """Values ``start`` to ``start + count`` (clipped to the store), as a fresh array:
        a bounded read for what must not hold the whole store (metrics/streamed)."""
        start = max(0, min(start, len(self)))
        count = max(0, min(count, len(self) - start))
        out = np.empty(count, dtype=np.float64)
        k = max(0, min(count, self._on_disk - start))  # from the file
        if k:
            assert self._file is not None
            self._file.flush()
            self._file.seek(start * 8)
            got = self._file.readinto(out[:k].view(np.uint8).data)
            self._file.seek(0, 2)
            if got != k * 8:
                raise OSError(f"samples file: read {got} of {k * 8} bytes")
        if count > k:
            lo = start + k - self._on_disk
            out[k:] = np.frombuffer(self._a, dtype=np.float64)[lo : lo + count - k]
        return out

    def values(self) -> NDArray[np.float64]:
        """The values so far, in order, as a read-only float64 array."""
        if self._file is None:
            v = np.frombuffer(self._a, dtype=np.float64)
        else:
            v = np.empty(len(self), dtype=np.float64)
            f = self._file
            f.flush()
            f.seek(0)
            got = f.readinto(v[: self._on_disk].view(np.uint8).data)
            if got != self._on_disk * 8:
                raise OSError(f"samples file: read {got} of {self._on_disk * 8} bytes")
            f.seek(0, 2)
            v[self._on_disk :] = np.frombuffer(self._a, dtype=np.float64)
        v.flags.writeable = False
        return v
