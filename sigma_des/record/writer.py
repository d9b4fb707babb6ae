"""Recording runs to MCAP: one channel per method and message kind, one timeline.

>>> import tempfile, os
>>> from sigma_des.record import Recorder, read_table
>>> path = os.path.join(tempfile.mkdtemp(), "run.mcap")
>>> with Recorder(path, scenario={"nodes": 1}) as rec:
...     run = rec.run("bides", mode="des")
...     run.trigger(frame=0, node=0, t_send=0.0, t_recv=0.001)
>>> read_table(path)[["method", "kind", "node", "frame", "t_send", "t_recv"]].values.tolist()
[['bides', 'trigger', 0.0, 0.0, 0.0, 0.001]]

Topics are ``/<method>/<kind>`` (kinds: :data:`~sigma_des.record.schemas.KINDS`);
message encoding ``json``, schema encoding ``jsonschema`` (see
:mod:`sigma_des.record.schemas` for the bodies). Bulk kinds (triggers, states,
commands) are grouped by **window**: the rows whose time (receive time, or send time
where the receive time is not known) falls in ``[k·window, (k+1)·window)`` form one
message with ``log_time = publish_time = (k+1)·window``; snapshots and render samples
are one message each at their time.

**The file's** ``log_time`` **never decreases.** Messages are held until they are due:
:meth:`MethodRecorder.advance` promises that no later message of that run is older
than ``t`` (the engines' tap calls it at every alignment and render tick), and the
recorder writes, in time order, everything of every run up to the earliest such
promise; :meth:`Recorder.close` writes the rest. A message that still arrives late
(older than what was written) is written with the last time written (its rows keep
their own times) and counted in the run's ``late_messages``. The file ends with a
summary section (schemas, channels, statistics, chunk indexes) so readers can seek.
Times are seconds: simulated time in DES runs, one monotonic clock since the run's
start in live runs.
"""

from __future__ import annotations

import heapq
import json
import math
import os
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from types import TracebackType
from typing import IO, Any

import numpy as np
import orjson
from mcap.writer import CompressionType, Writer
from numpy.typing import ArrayLike, NDArray

from sigma_des.record.delta import DeltaEncoder
from sigma_des.record.enu import poses_in_frame
from sigma_des.record.rows import Pending, pick, row_fields, rows_json
from sigma_des.record.schemas import KINDS, schema_bytes
from sigma_des.version import __version__

__all__ = ["MethodRecorder", "Recorder", "RECORD_MODES", "PROFILE"]

#: Storage modes of the state channel.
RECORD_MODES: tuple[str, ...] = ("full", "incremental")
#: MCAP profile string written in the header.
PROFILE = "sigma_des"
_RUN_MODES = ("des", "live")
_RANK = {k: i for i, k in enumerate(KINDS)}  # same-time order: bulk windows, then the rest
_END = 2**62  # "everything": later than any time in ns
_Msg = tuple[int, tuple[int, ...], int, bytes]  # log_ns, sort key, channel, data


def _ns(t: float) -> int:
    return max(0, round(t * 1e9)) if math.isfinite(t) else 0


def _ns_arr(t: NDArray[np.float64]) -> NDArray[np.int64]:
    out = np.zeros(t.shape, dtype=np.int64)
    ok = np.isfinite(t)
    out[ok] = np.maximum(np.round(t[ok] * 1e9), 0).astype(np.int64)
    return out


class Recorder:
    """An MCAP recording of one or more method runs on one timeline.

    Args:
        path: the ``.mcap`` file to create (an existing file is replaced unless
            ``overwrite`` is False).
        scenario: the resolved scenario (plain dict, e.g. ``to_dict(sc)``), stored as
            metadata ``scenario``.
        mode: ``full`` (every state) or ``incremental`` (delta-encoded states with a
            dead-band and keyframes; see :mod:`sigma_des.record.delta`).
        deadband_pos: incremental: dead-band on the dead-reckoned position (m).
        deadband_vel: incremental: dead-band on the velocity (m/s).
        deadband_att: incremental: dead-band on the attitude (rad).
        keyframe_every: incremental: frames between a node's keyframes.
        window: rows of the bulk kinds are grouped into messages per window (s; the
            engines use one trigger period).
        overwrite: replace an existing file (False: raise FileExistsError).

    Raises:
        ValueError: bad mode or parameter.
        FileExistsError: ``path`` exists and ``overwrite`` is False.
    """

    def __init__(
        self,
        path: str | Path,
        scenario: dict[str, Any] | None = None,
        mode: str = "full",
        *,
        deadband_pos: float = 0.05,
        deadband_vel: float = 0.1,
        deadband_att: float = 0.02,
        keyframe_every: int = 100,
        window: float = 0.01,
        overwrite: bool = True,
    ) -> None:
        if mode not in RECORD_MODES:
            raise ValueError(f"record mode must be one of {RECORD_MODES}, got {mode!r}")
        if min(deadband_pos, deadband_vel, deadband_att) < 0:
            raise ValueError("dead-bands must be >= 0")
        if keyframe_every < 1:
            raise ValueError("keyframe_every must be >= 1")
        if not (window >= 1e-6 and math.isfinite(window)):
            raise ValueError(f"window must be a finite number >= 1e-6 s, got {window}")
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"{self.path}: exists (not overwritten)")
        self.mode = mode
        self.params = {
            "deadband_pos": deadband_pos,
            "deadband_vel": deadband_vel,
            "deadband_att": deadband_att,
            "keyframe_every": keyframe_every,
        }
        self.window_ns = max(1, round(window * 1e9))
        self._fh: IO[bytes] = self.path.open("wb")
        self._w = Writer(self._fh, compression=CompressionType.ZSTD)
        self._w.start(profile=PROFILE, library=f"sigma_des {__version__}")
        meta = {"version": __version__, "record_mode": mode, "params": self.params,
                "window": self.window_ns / 1e9}
        self._w.add_metadata(
            "sigma_des",
            {
                "recording": json.dumps(meta, sort_keys=True),
                "scenario": json.dumps(scenario or {}, sort_keys=True, default=str),
            },
        )
        self._schemas: dict[str, int] = {}
        for kind in KINDS:
            name, data = schema_bytes(kind, mode)
            self._schemas[kind] = self._w.register_schema(name, "jsonschema", data)
        self.runs: dict[str, MethodRecorder] = {}
        self._parts: list[tuple[Path, dict[int, int]]] = []
        self._copied: dict[str, dict[str, str]] = {}
        self._copied_methods: set[str] = set()
        self._seq: dict[int, int] = {}
        self._last_ns = 0  # log time of the last message written
        self._written_to = -1  # everything up to this time is written
        self._late: dict[int, int] = {}  # channel -> messages written late
        self._closed = False

    def run(self, method: str, mode: str = "des") -> MethodRecorder:
        """The writer of one method's channels (``mode``: ``des`` or ``live``).

        Raises:
            ValueError: bad mode, a repeated method, or messages were already written
                (create every run first: the file is one timeline).
        """
        if mode not in _RUN_MODES:
            raise ValueError(f"run mode must be one of {_RUN_MODES}, got {mode!r}")
        if method in self.runs or method in self._copied_methods:
            raise ValueError(f"method {method!r} is already recorded in this file")
        if self._written_to >= 0 or self._parts:
            raise ValueError("create every run before the first advance() (one timeline), "
                             "and do not mix runs with copy_from")
        self.runs[method] = r = MethodRecorder(self, method, mode)
        return r

    def copy_from(self, part: str | Path) -> None:
        """Join every method of another recording (same record mode) into this one.

        Messages are copied as stored (no re-encoding) when the recorder closes,
        merged with the other parts' in ``log_time`` order; used to join the
        per-method files that worker processes write.

        Raises:
            ValueError: the part's record mode differs, it repeats a method, or this
                recorder records runs of its own.
        """
        from mcap.reader import make_reader

        if self.runs:
            raise ValueError("copy_from: this recorder records runs of its own")
        with Path(part).open("rb") as fh:
            reader = make_reader(fh)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            mode = json.loads(meta["sigma_des"]["recording"])["record_mode"]
            if mode != self.mode:
                raise ValueError(f"{part}: record mode {mode!r}, this file is {self.mode!r}")
            summary = reader.get_summary()
            assert summary is not None
            new = {ch.metadata["method"] for ch in summary.channels.values()}
            if new & (set(self.runs) | self._copied_methods):
                raise ValueError(f"{part}: repeats a method of this file: {sorted(new)}")
            self._copied_methods |= new
            ids = {cid: self._channel(ch.metadata["method"], ch.metadata["kind"],
                                      ch.metadata["run_mode"])
                   for cid, ch in summary.channels.items()}
            self._parts.append((Path(part), ids))
            for name, data in meta.items():
                if name.startswith("run:"):
                    self._copied[name] = data

    def _channel(self, method: str, kind: str, run_mode: str) -> int:
        meta = {"method": method, "kind": kind, "run_mode": run_mode, "record_mode": self.mode}
        cid = self._w.register_channel(
            f"/{method}/{kind}", "json", self._schemas[kind], metadata=meta
        )
        self._seq[cid] = 0
        self._late[cid] = 0
        return cid

    def _write(self, channel: int, log_ns: int, data: bytes, pub_ns: int | None = None) -> None:
        if log_ns < self._last_ns:  # late: keep the file's order, count it
            self._late[channel] += 1
            log_ns = self._last_ns
        self._last_ns = log_ns
        self._w.add_message(channel, log_ns, data, log_ns if pub_ns is None else pub_ns,
                            sequence=self._seq[channel])
        self._seq[channel] += 1

    def _pump(self) -> None:
        """Write what every run has promised (the earliest of their advances)."""
        up = min(r.mark for r in self.runs.values())
        if up > self._written_to:
            self._emit(up)

    def _emit(self, up_ns: int) -> None:
        msgs: list[_Msg] = []
        for i, r in enumerate(self.runs.values()):
            msgs += r.ready(up_ns, i)
        msgs.sort(key=lambda m: (m[0], m[1]))
        for log_ns, _key, ch, data in msgs:
            self._write(ch, log_ns, data)
        self._written_to = up_ns

    def _copy_parts(self) -> None:
        from mcap.reader import make_reader

        def part(j: int, fh: IO[bytes], ids: dict[int, int]) -> Iterator[tuple[Any, ...]]:
            for i, (_s, ch, m) in enumerate(make_reader(fh).iter_messages(log_time_order=True)):
                yield m.log_time, j, i, ids[ch.id], m.data, m.publish_time

        with ExitStack() as stack:
            its = [part(j, stack.enter_context(p.open("rb")), ids)
                   for j, (p, ids) in enumerate(self._parts)]
            for log_ns, _j, _i, cid, data, pub in heapq.merge(*its):
                self._write(cid, log_ns, data, pub)

    def close(self) -> None:
        """Write every pending message, the parts joined, the summary and indexes."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.runs:
                self._emit(_END)
            self._copy_parts()
            for m, r in self.runs.items():
                self._w.add_metadata(f"run:{m}", {k: str(v) for k, v in r.counts().items()})
            for name, data in self._copied.items():
                self._w.add_metadata(name, data)
            self._w.finish()
            self._fh.flush()
            os.fsync(self._fh.fileno())  # complete on disk before anyone renames it
        finally:
            self._fh.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class MethodRecorder:
    """Writer of one method's channels ``/<method>/<kind>``; made by :meth:`Recorder.run`."""

    def __init__(self, rec: Recorder, method: str, mode: str) -> None:
        self.rec = rec
        self.method = method
        self.run_mode = mode
        self._ch = {k: rec._channel(method, k, mode) for k in KINDS}
        self._pend = {k: Pending() for k in ("trigger", "state", "command")}
        self._singles: list[_Msg] = []
        self._n = dict.fromkeys(KINDS, 0)
        self.mark = -1  # advance(): no later message is older than this (ns)
        p = rec.params
        self.encoder = (
            DeltaEncoder(
                float(p["deadband_pos"]),
                float(p["deadband_vel"]),
                float(p["deadband_att"]),
                int(p["keyframe_every"]),
            )
            if rec.mode == "incremental"
            else None
        )

    # ------------------------------------------------------------ the contract API

    def trigger(self, frame: int, node: int, t_send: float, t_recv: float) -> None:
        """One trigger delivery to ``node`` (node -1, t_recv NaN: the trigger's issue)."""
        self.triggers([node], [frame], [t_send], [t_recv])

    def state(
        self,
        node: int,
        frame: int,
        t_send: float,
        t_recv: float,
        pos: ArrayLike,
        vel: ArrayLike,
        att: ArrayLike,
    ) -> None:
        """One state delivery (NED position m, NED velocity m/s, Euler angles rad)."""
        vals = np.concatenate([np.ravel(pos), np.ravel(vel), np.ravel(att)]).astype(float)
        if vals.size != 9:
            raise ValueError("pos, vel and att must have 3 values each")
        self.states([node], [frame], [t_send], [t_recv], vals[None, :])

    def command(
        self, node: int, frame: int, t_send: float, t_recv: float, values: ArrayLike
    ) -> None:
        """One command delivery (``values``: the command row, floats; NaN: keep)."""
        self.commands([node], [frame], [t_send], [t_recv], [np.ravel(values)])

    def snapshot(
        self,
        t: float,
        frame: int,
        frames: ArrayLike,
        pos: ArrayLike,
        att: ArrayLike | None = None,
    ) -> None:
        """An aligned snapshot shown at ``t`` (``pos``: n × 3 NED m; ``att``: n × 3 rad)."""
        fr = np.asarray(frames, dtype=np.int64).ravel()
        if self.rec.mode == "incremental":
            body: dict[str, Any] = {"t": t, "frame": int(frame),
                                    "frames": np.ascontiguousarray(fr)}
        else:
            body = poses_in_frame(t, int(frame), fr, np.asarray(pos, dtype=float), att)
        self._single("snapshot", t, body)

    def render(self, t: float, aoi: ArrayLike) -> None:
        """One render sample: the Age of Information of every node (s; NaN: none shown)."""
        a = np.array(aoi, dtype=float).ravel()
        a[~np.isfinite(a)] = -1.0
        self._single("render", t, {"t": t, "aoi": a})

    def advance(self, t: float) -> None:
        """Promise that no later message of this run is older than ``t`` (s).

        Everything of every run up to the earliest promise is then written.
        """
        self.mark = max(self.mark, _ns(t))
        self.rec._pump()

    # ------------------------------------------------------------ vectorised forms

    def triggers(
        self, nodes: ArrayLike, frames: ArrayLike, t_send: ArrayLike, t_recv: ArrayLike
    ) -> None:
        """Many trigger deliveries at once (arrays of equal length)."""
        self._bulk("trigger", nodes, frames, t_send, t_recv, {})

    def states(
        self,
        nodes: ArrayLike,
        frames: ArrayLike,
        t_send: ArrayLike,
        t_recv: ArrayLike,
        values: ArrayLike,
    ) -> None:
        """Many state deliveries (``values``: m × 9, pos, vel, att), in arrival order.

        The arrays are copied (callers may reuse their buffers).
        """
        self._bulk("state", nodes, frames, t_send, t_recv,
                   {"values": np.array(values, dtype=float).reshape(-1, 9)})

    def commands(
        self,
        nodes: ArrayLike,
        frames: ArrayLike,
        t_send: ArrayLike,
        t_recv: ArrayLike,
        values: ArrayLike,
    ) -> None:
        """Many command deliveries; ``values``: one row (sequence of floats) each."""
        if isinstance(values, np.ndarray) and values.ndim == 2:
            rows: list[NDArray[np.float64]] = list(np.array(values, dtype=float))
        else:
            rows = [np.array(r, dtype=float).ravel() for r in values]  # type: ignore[union-attr]
        self._bulk("command", nodes, frames, t_send, t_recv, {"values": rows})

    # ------------------------------------------------------------ internals

    def _bulk(self, kind: str, nodes: ArrayLike, frames: ArrayLike, t_send: ArrayLike,
              t_recv: ArrayLike, extra: dict[str, Any]) -> None:
        cols = {
            "node": np.array(nodes, dtype=np.int64).ravel(),
            "frame": np.array(frames, dtype=np.int64).ravel(),
            "t_send": np.array(t_send, dtype=float).ravel(),
            "t_recv": np.array(t_recv, dtype=float).ravel(),
            **extra,
        }
        m = cols["node"].size
        if any(len(v) != m for v in cols.values()):
            raise ValueError(f"{kind}s: the arrays must have equal lengths")
        if m:
            self._pend[kind].add(cols)
            self._n[kind] += m

    def _single(self, kind: str, t: float, body: dict[str, Any]) -> None:
        data = orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY)
        key = (_RANK[kind], len(self._singles))
        self._singles.append((_ns(t), key, self._ch[kind], data))
        self._n[kind] += 1

    def ready(self, up_ns: int, run: int) -> list[_Msg]:
        """Take the messages due by ``up_ns``: full windows and single messages."""
        out: list[_Msg] = []
        for kind, p in self._pend.items():
            if p.n:
                out += self._windows(kind, p, up_ns, run)
        keep = []
        for log_ns, key, ch, data in self._singles:
            if log_ns <= up_ns:
                out.append((log_ns, (run, *key), ch, data))
            else:
                keep.append((log_ns, key, ch, data))
        self._singles = keep
        return out

    def _windows(self, kind: str, p: Pending, up_ns: int, run: int) -> list[_Msg]:
        cols = p.take()
        ts, tr = cols["t_send"], cols["t_recv"]
        log = _ns_arr(np.where(np.isfinite(tr), tr, ts))
        w = self.rec.window_ns
        k = log // w
        due = (k + 1) * w <= up_ns
        if not due.all():
            p.add(pick(cols, np.flatnonzero(~due)))
        idx = np.flatnonzero(due)
        order = idx[np.lexsort((log[idx], k[idx]))]  # stable: arrival order within ties
        c = pick(cols, order)
        k = k[order]
        if kind == "state" and self.encoder is not None:  # encode in file order
            rows, key, vals = self.encoder.encode(c["node"], c["frame"], c["t_send"],
                                                  c["values"])
            o = np.argsort(rows, kind="stable")
            rows, key, vals = rows[o], key[o], vals[o]
            k = k[rows]
            c = {**pick(c, rows), "values": vals}
            fields = row_fields(kind, c, key.astype(np.int64))
        else:
            fields = row_fields(kind, c)
        if k.size == 0:
            return []
        body = rows_json(fields)
        starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        ends = np.r_[starts[1:], k.size]
        out: list[_Msg] = []
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            end_ns = int(k[a] + 1) * w
            data = b'{"t":%s,"rows":[{%s}]}' % (orjson.dumps(end_ns / 1e9),
                                                b"},{".join(body[a:b]))
            out.append((end_ns, (run, _RANK[kind], int(k[a])), self._ch[kind], data))
        return out

    def counts(self) -> dict[str, Any]:
        """Messages handed to this writer per kind, states stored, late messages."""
        out: dict[str, Any] = {f"{k}s": n for k, n in self._n.items()}
        out["run_mode"] = self.run_mode
        if self.encoder is not None:
            out["states_stored"] = self.encoder.written
        else:
            out["states_stored"] = self._n["state"]
        out["late_messages"] = sum(self.rec._late[c] for c in self._ch.values())
        return out
