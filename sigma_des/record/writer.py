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
:meth:`~sigma_des.record.method.MethodRecorder.advance` promises that no later message
of that run is older than ``t`` (the engines' tap calls it at every alignment and
render tick), and the recorder writes, in time order, everything of every run up to
the earliest such promise; :meth:`Recorder.close` writes the rest. A message that still arrives late
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

from mcap.writer import CompressionType, Writer

from sigma_des.record.method import MethodRecorder, Msg
from sigma_des.record.schemas import KINDS, schema_bytes
from sigma_des.version import __version__

__all__ = ["Recorder", "RECORD_MODES", "PROFILE"]

#: Storage modes of the state channel.
RECORD_MODES: tuple[str, ...] = ("full", "incremental")
#: MCAP profile string written in the header.
PROFILE = "sigma_des"
_RUN_MODES = ("des", "live")
_END = 2**62  # "everything": later than any time in ns
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
        self.late: dict[int, int] = {}  # channel -> messages written late
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
            ids = {cid: self.channel(ch.metadata["method"], ch.metadata["kind"],
                                      ch.metadata["run_mode"])
                   for cid, ch in summary.channels.items()}
            self._parts.append((Path(part), ids))
            for name, data in meta.items():
                if name.startswith("run:"):
                    self._copied[name] = data

    def channel(self, method: str, kind: str, run_mode: str) -> int:
        """A new channel ``/<method>/<kind>`` (its id)."""
        meta = {"method": method, "kind": kind, "run_mode": run_mode, "record_mode": self.mode}
        cid = self._w.register_channel(
            f"/{method}/{kind}", "json", self._schemas[kind], metadata=meta
        )
        self._seq[cid] = 0
        self.late[cid] = 0
        return cid

    def _write(self, channel: int, log_ns: int, data: bytes, pub_ns: int | None = None) -> None:
        if log_ns < self._last_ns:  # late: keep the file's order, count it
            self.late[channel] += 1
            log_ns = self._last_ns
        self._last_ns = log_ns
        self._w.add_message(channel, log_ns, data, log_ns if pub_ns is None else pub_ns,
                            sequence=self._seq[channel])
        self._seq[channel] += 1

    def pump(self) -> None:
        """Write what every run has promised (the earliest of their advances)."""
        up = min(r.mark for r in self.runs.values())
        if up > self._written_to:
            self._emit(up)

    def _emit(self, up_ns: int) -> None:
        msgs: list[Msg] = []
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
