"""The compiled core's cache hint: emitted as a prefetch, and changing no value."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from sigma_des.events.fast.prefetch import prefetch


@njit(cache=False, _nrt=False)
def _rows_sum(a, b, c, i, j):  # type: ignore[no-untyped-def]
    prefetch(a, i)  # a row of a 2-D int32 table (the event slots' int columns)
    prefetch(b[i], j)  # an element row of a 3-D table's view (the aligner's ring)
    prefetch(c, j)  # an element of a 1-D array
    return a[i, 1] + b[i, j, 2] + c[j]


def test_prefetch_is_emitted_and_reads_nothing_else() -> None:
    a = np.arange(12, dtype=np.int32).reshape(4, 3)
    b = np.arange(24, dtype=np.float64).reshape(2, 3, 4)
    c = np.array([10.0, 20.0, 30.0])
    before = (a.copy(), b.copy(), c.copy())
    # a[1, 1] = 4, b[1, 2, 2] = 12 + 8 + 2 = 22, c[2] = 30
    assert _rows_sum(a, b, c, 1, 2) == 56.0
    for x, y in zip((a, b, c), before, strict=True):
        np.testing.assert_array_equal(x, y)
    asm = _rows_sum.inspect_asm(_rows_sum.signatures[0])
    # seven hints, each a real prefetch instruction (x86 prefetcht0, arm64 prfm), not
    # folded away as a no-op: a row's first byte, one line on and its last element (a 2-D
    # table, a 3-D table's view), an element of a 1-D array
    assert sum(line.strip().startswith(("prefetch", "prfm")) for line in asm.splitlines()) == 7


def test_prefetch_takes_an_array_and_an_integer_row() -> None:
    @njit(cache=False)
    def bad(x):  # type: ignore[no-untyped-def]
        prefetch(x, 0)

    with pytest.raises(TypingError):
        bad(1.5)
