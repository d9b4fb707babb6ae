"""Row objects built column-wise: exact JSON, absent non-finite fields, row boundaries."""

from __future__ import annotations

import math

import numpy as np
import orjson
import pytest

from sigma_des.record.rows import array_tokens, rows_json


def test_rows_are_exact_json_with_non_finite_fields_left_out() -> None:
    rows = rows_json([
        ("node", np.array([3, -1, 7], dtype=np.int64)),
        ("t", np.array([math.nan, 0.25, -math.inf])),
        ("v", array_tokens(np.array([[1.5, 0.0], [2.0, -3.0], [0.1, 1e-7]]))),
    ])
    assert rows == [b'"node":3,"v":[1.5,0.0]', b'"node":-1,"t":0.25,"v":[2.0,-3.0]',
                    b'"node":7,"v":[0.1,1e-7]']
    assert orjson.loads(b"[{" + b"},{".join(rows) + b"}]")[1] == {
        "node": -1, "t": 0.25, "v": [2.0, -3.0]}


def test_empty_and_mismatched_columns() -> None:
    assert rows_json([("node", np.zeros(0, dtype=np.int64))]) == []
    assert array_tokens(np.zeros((2, 0))) == [b"[]", b"[]"]
    with pytest.raises(ValueError, match="column 'v' has 1 rows, expected 2"):
        rows_json([("node", np.array([1, 2])), ("v", [b"[1.0]"])])
