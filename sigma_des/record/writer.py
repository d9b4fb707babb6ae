"""Recording runs to MCAP: one channel per method and message kind.

>>> import tempfile, os
>>> from sigma_des.record import Recorder, read_table
>>> path = os.path.join(tempfile.mkdtemp(), "run.mcap")
>>> with Recorder(path, scenario={"nodes": 1}) as rec:
...     run = rec.run("bides", mode="des")
...     run.trigger(frame=0, node=0, t_send=0.0, t_recv=0.001)
>>> read_table(path)[["method", "kind", "node", "frame", "t_send", "t_recv"]].values.tolist()
[['bides', 'trigger', 0.0, 0.0, 0.0, 0.001]]

Topics are ``/<method>/<kind>`` (kinds: :data:`~sigma_des.record.schemas.KINDS`);
message encoding ``json``, schema encoding ``jsonschema``. Bulk kinds (triggers,
states, commands) are buffered and written as column batches of up to ``batch``
messages; every entry keeps its own send and receive time, and the MCAP message's
``publish_time``/``log_time`` are the batch's earliest send and latest receive
time (ns). The file ends with a summary section (schemas, channels, statistics,
chunk indexes) so readers can seek. Times are seconds: simulated time in DES
runs, one monotonic clock since the run's start in live runs.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import TracebackType
from typing import IO, Any

import numpy as np
import orjson
from mcap.writer import CompressionType, Writer
from numpy.typing import ArrayLike, NDArray

from sigma_des.record.delta import DeltaEncoder
from sigma_des.record.schemas import KINDS, schema_bytes
from sigma_des.version import __version__

__all__ = ["MethodRecorder", "Recorder", "RECORD_MODES", "PROFILE"]

#: Storage modes of the state channel.
RECORD_MODES: tuple[str, ...] = ("full", "incremental")
#: MCAP profile string written in the header.
PROFILE = "sigma_des"
_RUN_MODES = ("des", "live")


def _ns(t: float) -> int:
    return max(0, round(t * 1e9)) if math.isfinite(t) else 0


def _col(a: ArrayLike, dtype: Any = np.float64) -> NDArray[Any]:
    """A contiguous column orjson serialises natively (NaN → null)."""
    return np.ascontiguousarray(np.asarray(a, dtype=dtype))


class Recorder:
    """An MCAP recording of one or more method runs.

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
        batch: bulk kinds are written in batches of at most this many messages.
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
        batch: int = 1000,
        overwrite: bool = True,
    ) -> None:
        if mode not in RECORD_MODES:
            raise ValueError(f"record mode must be one of {RECORD_MODES}, got {mode!r}")
        if min(deadband_pos, deadband_vel, deadband_att) < 0:
            raise ValueError("dead-bands must be >= 0")
        if keyframe_every < 1 or batch < 1:
            raise ValueError("keyframe_every and batch must be >= 1")
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
        self.batch = batch
        self._fh: IO[bytes] = self.path.open("wb")
        self._w = Writer(self._fh, compression=CompressionType.ZSTD)
        self._w.start(profile=PROFILE, library=f"sigma_des {__version__}")
        meta = {"version": __version__, "record_mode": mode, "params": self.params}
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
        self._copied: dict[str, dict[str, str]] = {}
        self._copied_methods: set[str] = set()
        self._closed = False

    def run(self, method: str, mode: str = "des") -> MethodRecorder:
        """The writer of one method's channels (``mode``: ``des`` or ``live``)."""
        if mode not in _RUN_MODES:
            raise ValueError(f"run mode must be one of {_RUN_MODES}, got {mode!r}")
        if method in self.runs or method in self._copied_methods:
            raise ValueError(f"method {method!r} is already recorded in this file")
        self.runs[method] = r = MethodRecorder(self, method, mode)
        return r

    def copy_from(self, part: str | Path) -> None:
        """Copy every method of another recording (same record mode) into this one.

        Messages are copied as stored (no re-encoding); used to join the per-method
        files that worker processes write.

        Raises:
            ValueError: the part's record mode differs, or it repeats a method.
        """
        from mcap.reader import make_reader

        with Path(part).open("rb") as fh:
            reader = make_reader(fh)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            mode = json.loads(meta["sigma_des"]["recording"])["record_mode"]
            if mode != self.mode:
                raise ValueError(f"{part}: record mode {mode!r}, this file is {self.mode!r}")
            summary = reader.get_summary()
            assert summary is not None
            ids: dict[int, int] = {}
            new = {ch.metadata["method"] for ch in summary.channels.values()}
            if new & (set(self.runs) | self._copied_methods):
                raise ValueError(f"{part}: repeats a method of this file: {sorted(new)}")
            self._copied_methods |= new
            for cid, ch in summary.channels.items():
                method, kind = ch.metadata["method"], ch.metadata["kind"]
                ids[cid] = self._channel(method, kind, ch.metadata["run_mode"])
            for _s, ch, m in reader.iter_messages(log_time_order=False):
                self._w.add_message(ids[ch.id], m.log_time, m.data, m.publish_time, m.sequence)
            for name, data in meta.items():
                if name.startswith("run:"):
                    self._copied[name] = data

    def _channel(self, method: str, kind: str, run_mode: str) -> int:
        meta = {"method": method, "kind": kind, "run_mode": run_mode, "record_mode": self.mode}
        return self._w.register_channel(
            f"/{method}/{kind}", "json", self._schemas[kind], metadata=meta
        )

    def _add(self, channel: int, seq: int, t_send: float, t_recv: float, body: Any) -> None:
        data = orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY)  # NaN, inf -> null
        self._w.add_message(channel, _ns(t_recv), data, _ns(t_send), sequence=seq)

    def close(self) -> None:
        """Flush every run's buffers and write the summary and indexes."""
        if self._closed:
            return
        self._closed = True
        try:
            for r in self.runs.values():
                r.flush()
            for m, r in self.runs.items():
                self._w.add_metadata(f"run:{m}", {k: str(v) for k, v in r.counts().items()})
            for name, data in self._copied.items():
                self._w.add_metadata(name, data)
            self._w.finish()
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


class _Batch:
    """Column buffers of one bulk kind."""

    def __init__(self) -> None:
        self.cols: dict[str, list[Any]] = {}
        self.size = 0

    def extend(self, **cols: ArrayLike) -> None:
        for k, v in cols.items():
            arr = np.atleast_1d(np.array(v))  # a copy: callers may reuse their buffers
            self.cols.setdefault(k, []).append(arr)
        self.size += int(np.atleast_1d(np.asarray(next(iter(cols.values())))).shape[0])

    def take(self) -> dict[str, NDArray[Any]]:
        out = {k: np.concatenate(v) for k, v in self.cols.items()}
        self.cols = {}
        self.size = 0
        return out


class MethodRecorder:
    """Writer of one method's channels ``/<method>/<kind>``; made by :meth:`Recorder.run`."""

    def __init__(self, rec: Recorder, method: str, mode: str) -> None:
        self.rec = rec
        self.method = method
        self.run_mode = mode
        self._ch = {k: rec._channel(method, k, mode) for k in KINDS}
        self._seq = dict.fromkeys(KINDS, 0)
        self._buf = {k: _Batch() for k in ("trigger", "state", "command")}
        self._cmd_values: list[NDArray[np.float64]] = []
        self._pending: list[tuple[NDArray[Any], ...]] = []
        self._n_pending = 0
        self._n = dict.fromkeys(KINDS, 0)
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
        """One command delivery (``values``: the command row, floats)."""
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
            body: dict[str, Any] = {"t": t, "frame": int(frame), "frames": _col(fr, np.int64)}
        else:
            body = _poses_in_frame(t, int(frame), fr, np.asarray(pos, dtype=float), att)
        self._write("snapshot", t, t, body)
        self._n["snapshot"] += 1

    def render(self, t: float, aoi: ArrayLike) -> None:
        """One render sample: the Age of Information of every node (s; NaN: none)."""
        self._write("render", t, t, {"t": t, "aoi": _col(aoi).ravel()})
        self._n["render"] += 1

    # ------------------------------------------------------------ vectorised forms

    def triggers(
        self, nodes: ArrayLike, frames: ArrayLike, t_send: ArrayLike, t_recv: ArrayLike
    ) -> None:
        """Many trigger deliveries at once (arrays of equal length)."""
        self._bulk("trigger", node=nodes, frame=frames, t_send=t_send, t_recv=t_recv)

    def states(
        self,
        nodes: ArrayLike,
        frames: ArrayLike,
        t_send: ArrayLike,
        t_recv: ArrayLike,
        values: ArrayLike,
    ) -> None:
        """Many state deliveries (``values``: m × 9, pos, vel, att), in arrival order.

        The arrays are copied (callers may reuse their buffers) and encoded once
        ``batch`` states are pending.
        """
        nd = np.array(nodes, dtype=np.int64).ravel()
        v = np.array(values, dtype=float).reshape(-1, 9)
        self._pending.append((nd, np.array(frames, dtype=np.int64).ravel(),
                              np.array(t_send, dtype=float).ravel(),
                              np.array(t_recv, dtype=float).ravel(), v))
        self._n_pending += nd.size
        self._n["state"] += nd.size
        if self._n_pending >= self.rec.batch:
            self._encode_pending()

    def _encode_pending(self) -> None:
        if not self._pending:
            return
        nd, fr, ts, tr, v = (np.concatenate(c) for c in zip(*self._pending, strict=True))
        self._pending = []
        self._n_pending = 0
        cols: dict[str, Any]
        if self.encoder is not None:
            rows, key, v = self.encoder.encode(nd, fr, ts, v)
            nd, fr, ts, tr = nd[rows], fr[rows], ts[rows], tr[rows]
            cols = {"key": key}
        else:
            cols = {}
        names = ("x", "y", "z", "vx", "vy", "vz", "phi", "theta", "psi")
        cols.update({c: v[:, j] for j, c in enumerate(names)})
        if nd.size:
            self._buf["state"].extend(node=nd, frame=fr, t_send=ts, t_recv=tr, **cols)
            if self._buf["state"].size >= self.rec.batch:
                self._flush("state")

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
            rows = [np.asarray(r, dtype=float).ravel() for r in values]  # type: ignore[union-attr]
        self._cmd_values.extend(rows)
        self._bulk("command", node=nodes, frame=frames, t_send=t_send, t_recv=t_recv)

    # ------------------------------------------------------------ internals

    def _bulk(self, kind: str, **cols: ArrayLike) -> None:
        b = self._buf[kind]
        before = b.size
        b.extend(**cols)
        self._n[kind] += b.size - before
        if b.size >= self.rec.batch:
            self._flush(kind)

    def _flush(self, kind: str) -> None:
        b = self._buf[kind]
        if b.size == 0:
            return
        cols = b.take()
        body: dict[str, Any] = {"seq": self._seq[kind]}
        for k, v in cols.items():
            body[k] = _col(v, np.int64 if k in ("node", "frame", "key") else np.float64)
        if kind == "command":
            vals = self._cmd_values
            if len({r.size for r in vals}) == 1:
                body["values"] = _col(np.stack(vals))
            else:
                body["values"] = [_col(r) for r in vals]
            self._cmd_values = []
        ts = cols["t_send"].astype(float)
        tr = cols["t_recv"].astype(float)
        t_pub = float(np.nanmin(ts)) if np.isfinite(ts).any() else 0.0
        t_log = float(np.nanmax(tr)) if np.isfinite(tr).any() else float(np.nanmax(ts))
        self._write(kind, t_pub, t_log, body)

    def _write(self, kind: str, t_send: float, t_recv: float, body: Any) -> None:
        self.rec._add(self._ch[kind], self._seq[kind], t_send, t_recv, body)
        self._seq[kind] += 1

    def flush(self) -> None:
        """Write every buffered batch."""
        self._encode_pending()
        for kind in self._buf:
            self._flush(kind)

    def counts(self) -> dict[str, Any]:
        """Messages handed to this writer per kind, plus states actually stored."""
        out: dict[str, Any] = {f"{k}s": n for k, n in self._n.items()}
        out["run_mode"] = self.run_mode
        if self.encoder is not None:
            out["states_stored"] = self.encoder.written
        else:
            out["states_stored"] = self._n["state"]
        return out


def _poses_in_frame(
    t: float, frame: int, frames: NDArray[np.int64], pos: NDArray[np.float64],
    att: ArrayLike | None,
) -> dict[str, Any]:
    """A ``foxglove.PosesInFrame`` body (NED frame ``ned``) with frame fields added."""
    n = frames.size
    p = pos.reshape(n, 3)
    if att is None:
        q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    else:
        q = _quat(np.asarray(att, dtype=float).reshape(n, 3))
    ok = np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1)
    poses = [
        {
            "position": {"x": a[0], "y": a[1], "z": a[2]},
            "orientation": {"x": b[0], "y": b[1], "z": b[2], "w": b[3]},
        }
        for a, b in zip(p[ok].tolist(), q[ok].tolist(), strict=True)
    ]
    sec = int(max(t, 0.0))
    nsec = min(999_999_999, max(0, round((max(t, 0.0) - sec) * 1e9)))
    return {
        "timestamp": {"sec": sec, "nsec": nsec},
        "frame_id": "ned",
        "poses": poses,
        "frame": frame,
        "frames": _col(frames, np.int64),
        "nodes": np.flatnonzero(ok).astype(np.int64),
    }


def _quat(att: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quaternions (x, y, z, w) of Z-Y-X Euler angles (phi, theta, psi)."""
    hp, ht, hs = att[:, 0] / 2, att[:, 1] / 2, att[:, 2] / 2
    cp, sp, ct, st, cs, ss = np.cos(hp), np.sin(hp), np.cos(ht), np.sin(ht), np.cos(hs), np.sin(hs)
    return np.stack(
        [
            sp * ct * cs - cp * st * ss,
            cp * st * cs + sp * ct * ss,
            cp * ct * ss - sp * st * cs,
            cp * ct * cs + sp * st * ss,
        ],
        axis=1,
    )
