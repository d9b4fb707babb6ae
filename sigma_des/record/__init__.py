"""Recording runs to MCAP and reading them back (the replay memory's storage).

The writer (:class:`Recorder`) makes one channel per method and message kind with
JSON schemas that Foxglove and Lichtblick load (rows per trigger period; aligned
snapshots as Foxglove's ``foxglove.PosesInFrame`` in a z-up frame), on one timeline
whose ``log_time`` never decreases; the reader returns tidy tables (:func:`read_table`) and
per-node states (:func:`read_states`). ``mode="incremental"`` stores states as
per-node deltas with a dead-band and keyframes (:mod:`sigma_des.record.delta`). Every
snapshot moves the frame ``<method>/swarm`` (``/<method>/tf``) to the swarm's centre, and
:func:`foxglove_layout` is a Foxglove layout whose 3-D panel follows it.
"""

from sigma_des.extras import need_import

need_import("sigma_des.record", "mcap", "orjson", extra="record")

from sigma_des.record.layout import foxglove_layout  # noqa: E402  (after the check of the extra)
from sigma_des.record.method import MethodRecorder  # noqa: E402
from sigma_des.record.reader import (  # noqa: E402
    RecordError,
    Recording,
    StateTable,
    open_recording,
    read_states,
    read_table,
)
from sigma_des.record.writer import RECORD_MODES, Recorder  # noqa: E402

__all__ = [
    "MethodRecorder",
    "RECORD_MODES",
    "RecordError",
    "Recorder",
    "Recording",
    "StateTable",
    "foxglove_layout",
    "open_recording",
    "read_states",
    "read_table",
]
