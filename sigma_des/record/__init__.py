"""Recording runs to MCAP and reading them back (the replay memory's storage).

The writer (:class:`Recorder`) makes one channel per method and message kind with
JSON schemas that Foxglove and Lichtblick load (rows per trigger period; aligned
snapshots as Foxglove's ``foxglove.PosesInFrame`` in a z-up frame), on one timeline
whose ``log_time`` never decreases; the reader returns tidy tables (:func:`read_table`) and
per-node states (:func:`read_states`). ``mode="incremental"`` stores states as
per-node deltas with a dead-band and keyframes (:mod:`sigma_des.record.delta`).
"""

from sigma_des.record.method import MethodRecorder
from sigma_des.record.reader import (
    RecordError,
    Recording,
    StateTable,
    open_recording,
    read_states,
    read_table,
)
from sigma_des.record.writer import RECORD_MODES, Recorder

__all__ = [
    "MethodRecorder",
    "RECORD_MODES",
    "RecordError",
    "Recorder",
    "Recording",
    "StateTable",
    "open_recording",
    "read_states",
    "read_table",
]
