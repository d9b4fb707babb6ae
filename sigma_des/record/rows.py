"""Rows of the bulk channels: pending columns, their fields, JSON built column-wise.

Each column is serialised once by ``orjson`` and split into one token per row; the
rows are then assembled by list-slice assignment and one ``bytes.join``. A float
that is not finite leaves its field out of that row (the schemas' rule: absent, never
``null``). Values are numbers only, so ``},{`` can only be a row boundary.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain
from typing import Any

import numpy as np
import orjson
from numpy.typing import NDArray

__all__ = ["POSE_COLS", "Pending", "array_tokens", "pick", "row_fields", "rows_json"]

#: State row fields after node, frame, times (NED m, m/s; Euler rad).
POSE_COLS = ("x", "y", "z", "vx", "vy", "vz", "phi", "theta", "psi")

_OPT = orjson.OPT_SERIALIZE_NUMPY


def _tokens(col: NDArray[Any]) -> list[bytes]:
    """One JSON token per entry of a 1-D int or float column."""
    return orjson.dumps(np.ascontiguousarray(col), option=_OPT)[1:-1].split(b",")


def array_tokens(values: NDArray[Any]) -> list[bytes]:
    """One JSON array token (``[a,b,…]``) per row of a 2-D numeric array."""
    m, w = values.shape
    if m == 0:
        return []
    if w == 0:
        return [b"[]"] * m
    body = orjson.dumps(np.ascontiguousarray(values), option=_OPT)[2:-2].split(b"],[")
    return [b"[" + b + b"]" for b in body]


def rows_json(cols: Sequence[tuple[str, NDArray[Any] | list[bytes]]]) -> list[bytes]:
    """The rows as JSON object bodies (without the braces), one per row.

    Args:
        cols: ``(key, column)`` pairs in field order; a column is a 1-D int or float
            array or a list of ready JSON tokens (e.g. :func:`array_tokens`). The first
            column must be an int column (it is never left out).

    Returns:
        ``[b'"node":3,"frame":5,…', …]``; ``b"{" + b"},{".join(rows) + b"}"`` is their
        JSON array body.
    """
    n = len(cols[0][1])
    if n == 0:
        return []
    c = len(cols)
    pieces: list[bytes] = [b""] * (2 * n * c)
    for j, (key, col) in enumerate(cols):
        pre = (b'"%s":' if j == 0 else b',"%s":') % key.encode()
        if isinstance(col, list):
            toks, bad = col, np.zeros(0, dtype=np.intp)
        else:
            toks = _tokens(col)
            finite = np.isfinite(col) if col.dtype.kind == "f" else np.ones(n, dtype=bool)
            bad = np.flatnonzero(~finite)
        if len(toks) != n:
            raise ValueError(f"column {key!r} has {len(toks)} rows, expected {n}")
        pieces[2 * j :: 2 * c] = [pre] * n
        pieces[2 * j + 1 :: 2 * c] = toks
        for i in bad.tolist():  # absent, not null
            pieces[2 * (i * c + j)] = pieces[2 * (i * c + j) + 1] = b""
    pieces[2 * c :: 2 * c] = [b"},{" + pieces[0]] * (n - 1)  # row boundaries
    return b"".join(pieces).split(b"},{")


def row_fields(kind: str, c: dict[str, Any], key: NDArray[np.int64] | None = None
               ) -> list[tuple[str, Any]]:
    """The row fields of ``kind`` in schema order (``key``: delta rows' keyframe flags)."""
    f: list[tuple[str, Any]] = [(n, c[n]) for n in ("node", "frame", "t_send", "t_recv")]
    if key is not None:
        f.append(("key", key))
    if kind == "state":
        f += [(n, np.ascontiguousarray(c["values"][:, j])) for j, n in enumerate(POSE_COLS)]
    elif kind == "command":
        vals: list[NDArray[np.float64]] = c["values"]
        if len({v.size for v in vals}) == 1:
            v = np.stack(vals)
            ok = np.isfinite(v)
            f.append(("values", array_tokens(np.where(ok, v, 0.0))))
            f.append(("valid", array_tokens(ok.astype(np.int64))))
        else:  # rows of different widths: one at a time
            f.append(("values", [orjson.dumps(np.where(np.isfinite(r), r, 0.0),
                                              option=orjson.OPT_SERIALIZE_NUMPY)
                                 for r in vals]))
            f.append(("valid", [orjson.dumps(np.isfinite(r).astype(np.int64),
                                             option=orjson.OPT_SERIALIZE_NUMPY)
                                for r in vals]))
    return f


class Pending:
    """Rows of one bulk kind not written yet (column chunks, copied on entry)."""

    def __init__(self) -> None:
        self.chunks: list[dict[str, Any]] = []
        self.n = 0

    def add(self, cols: dict[str, Any]) -> None:
        self.chunks.append(cols)
        self.n += len(cols["node"])

    def take(self) -> dict[str, Any]:
        """Every pending row as one column set (and none left pending)."""
        out: dict[str, Any] = {}
        for k in self.chunks[0]:
            parts = [c[k] for c in self.chunks]
            out[k] = (list(chain.from_iterable(parts)) if isinstance(parts[0], list)
                      else np.concatenate(parts))
        self.chunks, self.n = [], 0
        return out


def pick(cols: dict[str, Any], idx: NDArray[np.intp]) -> dict[str, Any]:
    """Rows ``idx`` of every column (array or list)."""
    return {k: [v[i] for i in idx.tolist()] if isinstance(v, list) else v[idx]
            for k, v in cols.items()}
