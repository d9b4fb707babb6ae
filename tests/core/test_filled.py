"""core/filled.py: ``filled`` is ``np.full`` with the dtype given, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.filled import filled


@pytest.mark.parametrize(("shape", "value", "dtype"), [
    (5, np.nan, np.float64), ((3, 4), -np.inf, np.float64), ((2, 0), 1.5, np.float64),
    (7, -1, np.int64), ((2, 3), -2, np.int64), (4, 3, np.uint8), ((1, 1), -1, np.int32),
    (3, 0.1, np.float64), ((), 2.0, np.float64),
])
def test_filled_is_np_full(shape: int | tuple[int, ...], value: float, dtype: type) -> None:
    got, want = filled(shape, value, dtype), np.full(shape, value, dtype=dtype)
    assert got.dtype == want.dtype and got.shape == want.shape
    assert got.tobytes() == want.tobytes()
    assert got.flags.c_contiguous and got.flags.writeable and got.flags.owndata


def test_filled_is_float64_by_default_whatever_the_value() -> None:
    assert filled(3, -1).dtype == np.float64 and filled(3, -1).tolist() == [-1.0] * 3
    assert np.isnan(filled((2, 2), np.nan)).all()
