"""Reading MCAP recordings back: tidy tables and per-node state arrays.

:func:`read_table` gives one row per recorded delivery, snapshot and render sample
(``method, kind, node, frame, t_send, t_recv``, NaN where not applicable or absent);
:func:`read_states` gives, per method, the recorded states with the incremental
encoding undone. Every problem with the file (missing, not MCAP, truncated, corrupt,
unknown or older schema) raises :class:`RecordError` naming the file and what is wrong.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import chain
from operator import itemgetter
from pathlib import Path
from typing import Any

import numpy as np
import orjson
from mcap.reader import make_reader
from numpy.typing import NDArray

from sigma_des.errors import ConfigError
from sigma_des.record.delta import decode
from sigma_des.record.rows import POSE_COLS
from sigma_des.record.schemas import KINDS, LEGACY, READABLE, SCHEMAS, TABLE_KINDS

__all__ = ["Recording", "RecordError", "StateTable", "open_recording", "read_states",
           "read_table"]

TABLE_COLUMNS = ("method", "kind", "node", "frame", "t_send", "t_recv")
_KNOWN = {name for name, _s in SCHEMAS.values()} | READABLE
_MAGIC = b"\x89MCAP0\r\n"


class RecordError(ConfigError):
    """A recording cannot be read (the key is the file)."""


@dataclass
class StateTable:
    """One method's recorded states, in recorded order.

    Attributes:
        node, frame: per row.
        t_send, t_recv: generation and receive time (s).
        pos, vel, att: ``(m, 3)`` NED position (m), NED velocity (m/s), Euler angles (rad).
    """

    node: NDArray[np.int64]
    frame: NDArray[np.int64]
    t_send: NDArray[np.float64]
    t_recv: NDArray[np.float64]
    pos: NDArray[np.float64]
    vel: NDArray[np.float64]
    att: NDArray[np.float64]


@dataclass
class Recording:
    """What a recording holds (from its summary and metadata).

    Attributes:
        path: the file.
        methods: recorded methods, in channel order.
        record_mode: ``full`` or ``incremental``.
        scenario: the stored scenario dict.
        params: the recorder's parameters (dead-bands, keyframe period).
        runs: per method, the counts stored when the recording was closed.
        topics: topic -> (method, kind).
    """

    path: Path
    methods: list[str]
    record_mode: str
    scenario: dict[str, Any]
    params: dict[str, Any]
    runs: dict[str, dict[str, str]]
    topics: dict[str, tuple[str, str]]
    _cache: dict[str, list[tuple[int, bytes]]] | None = field(default=None, repr=False)

    def messages(self, kind: str, method: str) -> Iterator[dict[str, Any]]:
        """Decoded bodies of ``/<method>/<kind>``, in write order."""
        topic = f"/{method}/{kind}"
        raw = self.prefetch([topic]) if topic not in (self._cache or {}) else self._cache or {}
        try:
            for _seq, data in sorted(raw.get(topic, []), key=lambda x: x[0]):
                body = orjson.loads(data)
                if not isinstance(body, dict):
                    raise ValueError("a message is not a JSON object")
                yield body
        except ValueError as e:  # orjson.JSONDecodeError is a ValueError
            raise RecordError(str(self.path), f"corrupt data on {topic}: {e}") from None

    def prefetch(self, topics: list[str]) -> dict[str, list[tuple[int, bytes]]]:
        """Read the messages of ``topics`` in one pass over the file and keep their bytes."""
        out: dict[str, list[tuple[int, bytes]]] = {t: [] for t in topics}
        try:
            with self.path.open("rb") as fh:
                it = make_reader(fh).iter_messages(topics=topics, log_time_order=False)
                for _s, ch, m in it:
                    out[ch.topic].append((m.sequence, m.data))
        except Exception as e:  # untrusted file: any decoding failure means corrupt
            raise RecordError(str(self.path), f"corrupt data: {type(e).__name__}: {e}") from None
        self._cache = {**(self._cache or {}), **out}
        return self._cache


def open_recording(path: str | Path) -> Recording:
    """Open and check a recording (header, summary, schemas, metadata).

    Raises:
        RecordError: missing file, not MCAP, truncated (no summary), unknown schema.
    """
    p = Path(path)
    if not p.is_file():
        raise RecordError(str(p), "recording not found")
    with p.open("rb") as fh:
        head = fh.read(len(_MAGIC))
        fh.seek(max(0, p.stat().st_size - len(_MAGIC)))
        tail = fh.read()
    if head != _MAGIC:
        raise RecordError(str(p), "not a readable MCAP file (no MCAP magic at the start)")
    if tail != _MAGIC:
        raise RecordError(str(p), "truncated or unfinished recording: no MCAP magic at the end")
    try:
        with p.open("rb") as fh:
            reader = make_reader(fh)
            header = reader.get_header()
            summary = reader.get_summary()
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    except Exception as e:  # untrusted file: any decoding failure means corrupt
        raise RecordError(str(p), f"corrupt MCAP file ({type(e).__name__}: {e})") from None
    if summary is None:
        raise RecordError(str(p), "truncated or unfinished recording: no summary section")
    if header.profile != "sigma_des" or "sigma_des" not in meta:
        raise RecordError(str(p), f"not a sigma_des recording (profile {header.profile!r})")
    topics: dict[str, tuple[str, str]] = {}
    methods: list[str] = []
    for ch in summary.channels.values():
        sch = summary.schemas.get(ch.schema_id)
        name = sch.name if sch is not None else "<none>"
        if name in LEGACY:
            raise RecordError(str(p), f"schema {name!r} on topic {ch.topic!r} is the older "
                              "column-batch layout, which this version does not read; record "
                              "the run again")
        if name not in _KNOWN:
            raise RecordError(str(p), f"unknown schema {name!r} on topic {ch.topic!r}")
        parts = ch.topic.split("/")
        if len(parts) != 3 or parts[2] not in KINDS:
            raise RecordError(str(p), f"unknown topic {ch.topic!r}")
        topics[ch.topic] = (parts[1], parts[2])
        if parts[1] not in methods:
            methods.append(parts[1])
    try:
        rec = json.loads(meta["sigma_des"]["recording"])
        scen = json.loads(meta["sigma_des"].get("scenario", "{}"))
    except (KeyError, ValueError) as e:
        raise RecordError(str(p), f"bad sigma_des metadata: {e}") from None
    runs = {k[4:]: v for k, v in meta.items() if k.startswith("run:")}
    return Recording(p, methods, rec.get("record_mode", "full"), scen, rec.get("params", {}),
                     runs, topics)


def read_states(path: str | Path, method: str | None = None) -> dict[str, StateTable]:
    """Recorded states per method (incremental encoding undone).

    Args:
        path: the recording.
        method: only this method (default: every recorded method).

    Raises:
        RecordError: unreadable file, or ``method`` not recorded.
    """
    rec = open_recording(path)
    methods = rec.methods if method is None else [method]
    if method is not None and method not in rec.methods:
        raise RecordError(str(rec.path), f"method {method!r} not recorded; has {rec.methods}")
    rec.prefetch([f"/{m}/state" for m in methods])
    return {m: _states(rec, m) for m in methods}


def _rows(rec: Recording, kind: str, method: str) -> list[dict[str, Any]]:
    """Every row of the window messages of ``/<method>/<kind>``, in file order."""
    try:
        return list(chain.from_iterable(body["rows"] for body in rec.messages(kind, method)))
    except (KeyError, TypeError) as e:
        raise RecordError(str(rec.path), f"corrupt {kind} message of {method!r}: "
                          f"missing {e}") from None


def _column(rows: list[dict[str, Any]], key: str, dtype: Any = float) -> NDArray[Any]:
    """Field ``key`` of every row (an absent field is NaN)."""
    try:  # the common case, at C speed: every row has the field
        return np.fromiter(map(itemgetter(key), rows), dtype=dtype, count=len(rows))
    except KeyError:
        nan = float("nan")
        return np.fromiter((r.get(key, nan) for r in rows), dtype=dtype, count=len(rows))


def _table(rows: list[dict[str, Any]], keys: tuple[str, ...]) -> NDArray[np.float64]:
    """``(len(rows), len(keys))`` floats of the rows' fields (an absent field is NaN)."""
    if not rows:
        return np.zeros((0, len(keys)))
    try:  # the common case, at C speed: every row has every field
        return np.array(list(map(itemgetter(*keys), rows)), dtype=float).reshape(-1, len(keys))
    except KeyError:
        return np.stack([_column(rows, k) for k in keys], axis=1)


def _states(rec: Recording, method: str) -> StateTable:
    rows = _rows(rec, "state", method)
    incremental = rec.record_mode == "incremental"
    try:
        node = _column(rows, "node", np.int64)
        frame = _column(rows, "frame", np.int64)
        tab = _table(rows, ("t_send", "t_recv", *(("key",) if incremental else ()), *POSE_COLS))
        vals = tab[:, -9:]
        if incremental:
            vals = decode(node, tab[:, 2].astype(np.int8), vals)
        return StateTable(node, frame, tab[:, 0].copy(), tab[:, 1].copy(), vals[:, 0:3],
                          vals[:, 3:6], vals[:, 6:9])
    except (ValueError, TypeError) as e:  # e.g. a row without node, a non-number
        raise RecordError(str(rec.path), f"corrupt states of {method!r}: {e}") from None


def read_table(path: str | Path) -> Any:
    """One row per recorded delivery, snapshot and render sample.

    Columns ``method, kind, node, frame, t_send, t_recv``; a delivery's absent
    ``t_recv`` (a trigger issue, a command send) is NaN.

    ``node``/``frame`` are floats (NaN where not applicable: render samples have no
    node or frame, snapshots no node); ``t_send`` is NaN for snapshots and render
    samples, whose time is ``t_recv`` (the time shown). Incremental recordings list
    the stored states only. The swarm frame's transforms (``/<method>/tf``, derived from
    the snapshots for the viewers) are not listed.

    Returns:
        A ``pandas.DataFrame``.

    Raises:
        RecordError: the file cannot be read.
    """
    import pandas as pd

    rec = open_recording(path)
    rec.prefetch([t for t, (_m, kind) in rec.topics.items() if kind in TABLE_KINDS])
    frames: list[Any] = []
    for method in rec.methods:
        for kind in TABLE_KINDS:
            frames.append(_kind_rows(rec, method, kind))
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    if df.empty:
        return pd.DataFrame({c: pd.Series(dtype=object if c in ("method", "kind") else float)
                             for c in TABLE_COLUMNS})
    return df[list(TABLE_COLUMNS)]


def _kind_rows(rec: Recording, method: str, kind: str) -> Any:
    import pandas as pd

    cols: dict[str, NDArray[np.float64]]
    if kind in ("trigger", "state", "command"):
        rows = _rows(rec, kind, method)
        try:
            cols = {k: _column(rows, k) for k in ("node", "frame", "t_send", "t_recv")}
        except (ValueError, TypeError) as e:
            raise RecordError(str(rec.path), f"corrupt {kind} message of {method!r}: {e}"
                              ) from None
    else:
        t: list[float] = []
        frame: list[Any] = []
        try:
            for b in rec.messages(kind, method):
                if kind == "snapshot":
                    t.append(b["t"] if "t" in b
                             else b["timestamp"]["sec"] + b["timestamp"]["nsec"] * 1e-9)
                    frame.append(b["frame"])
                else:
                    t.append(b["t"])
                    frame.append(None)
        except (KeyError, TypeError) as e:
            raise RecordError(str(rec.path), f"corrupt {kind} message of {method!r}: "
                              f"{e}") from None
        n = len(t)
        cols = {"node": np.full(n, np.nan), "frame": np.array(frame, dtype=float),
                "t_send": np.full(n, np.nan), "t_recv": np.array(t, dtype=float)}
    return pd.DataFrame({"method": method, "kind": kind, **cols})
