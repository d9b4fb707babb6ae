"""The writer of one method's channels in a recording (:meth:`Recorder.run
<sigma_des.record.writer.Recorder.run>`): rows in, messages out when they are due.

A :class:`MethodRecorder` takes deliveries one by one or as arrays, holds the bulk kinds
(triggers, states, commands) until their window is due and the single ones (snapshots,
render samples) until their time, and hands them to its recording (:class:`RunSink`) in
the file's order (:meth:`MethodRecorder.ready`); the recording writes them. With the
``incremental`` mode its states are delta-encoded (:mod:`sigma_des.record.delta`).
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np
import orjson
from numpy.typing import ArrayLike, NDArray

from sigma_des.record.delta import DeltaEncoder
from sigma_des.record.enu import poses_in_frame, swarm_transform
from sigma_des.record.rows import Pending, pick, row_fields, rows_json
from sigma_des.record.schemas import KINDS

__all__ = ["MethodRecorder", "Msg", "RunSink", "SNAPSHOT_DECIMALS"]

#: Decimal places of positions (m) and quaternions in ``incremental`` snapshots.
SNAPSHOT_DECIMALS = (2, 4)
RANK = {k: i for i, k in enumerate(KINDS)}  # same-time order: bulk windows, then the rest
Msg = tuple[int, tuple[int, ...], int, bytes]  # log_ns, sort key, channel, data


def _ns(t: float) -> int:
    return max(0, round(t * 1e9)) if math.isfinite(t) else 0


def _ns_arr(t: NDArray[np.float64]) -> NDArray[np.int64]:
    out = np.zeros(t.shape, dtype=np.int64)
    ok = np.isfinite(t)
    out[ok] = np.maximum(np.round(t[ok] * 1e9), 0).astype(np.int64)
    return out


class RunSink(Protocol):
    """What a method's writer needs of its recording (:class:`~sigma_des.record.writer.
    Recorder`).

    Attributes:
        mode: ``full`` or ``incremental``.
        params: the dead-bands and keyframe interval (``incremental``).
        window_ns: the bulk kinds' window (ns).
        late: messages written late, per channel.
    """

    mode: str
    params: dict[str, Any]
    window_ns: int
    late: dict[int, int]

    def channel(self, method: str, kind: str, run_mode: str) -> int:
        """A new channel ``/<method>/<kind>`` (its id)."""
        ...

    def pump(self) -> None:
        """Write what every run has promised."""
        ...


class MethodRecorder:
    """Writer of one method's channels ``/<method>/<kind>``; made by :meth:`Recorder.run`."""

    def __init__(self, rec: RunSink, method: str, mode: str) -> None:
        self.rec = rec
        self.method = method
        self.run_mode = mode
        self._ch = {k: rec.channel(method, k, mode) for k in KINDS}
        self._pend = {k: Pending() for k in ("trigger", "state", "command")}
        self._singles: list[Msg] = []
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
        """An aligned snapshot shown at ``t`` (``pos``: n × 3 NED m; ``att``: n × 3 rad).

        In ``incremental`` mode the poses are rounded to :data:`SNAPSHOT_DECIMALS` (a
        display's precision; about a quarter of the size of exact poses).

        Also moves the frame ``<method>/swarm`` to the centre of the finite positions
        (``/<method>/tf``; none if no position is finite), in both record modes.
        """
        fr = np.asarray(frames, dtype=np.int64).ravel()
        p = np.asarray(pos, dtype=float)
        rounded = SNAPSHOT_DECIMALS if self.rec.mode == "incremental" else None
        self._single("snapshot", t, poses_in_frame(t, int(frame), fr, p, att, rounded))
        tf = swarm_transform(t, self.method, p)
        if tf is not None:
            self._single("tf", t, tf)

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
        self.rec.pump()

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
        key = (RANK[kind], len(self._singles))
        self._singles.append((_ns(t), key, self._ch[kind], data))
        self._n[kind] += 1

    def ready(self, up_ns: int, run: int) -> list[Msg]:
        """Take the messages due by ``up_ns``: full windows and single messages."""
        out: list[Msg] = []
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

    def _windows(self, kind: str, p: Pending, up_ns: int, run: int) -> list[Msg]:
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
        out: list[Msg] = []
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            end_ns = int(k[a] + 1) * w
            data = b'{"t":%s,"rows":[{%s}]}' % (orjson.dumps(end_ns / 1e9),
                                                b"},{".join(body[a:b]))
            out.append((end_ns, (run, RANK[kind], int(k[a])), self._ch[kind], data))
        return out

    def counts(self) -> dict[str, Any]:
        """Messages handed to this writer per kind, states stored, late messages."""
        out: dict[str, Any] = {f"{k}s": n for k, n in self._n.items()}
        out["run_mode"] = self.run_mode
        if self.encoder is not None:
            out["states_stored"] = self.encoder.written
        else:
            out["states_stored"] = self._n["state"]
        out["late_messages"] = sum(self.rec.late[c] for c in self._ch.values())
        return out
