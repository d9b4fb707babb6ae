"""JSON schemas of the recorded channels (MCAP ``jsonschema`` encoding).

One channel per method and message kind, topic ``/<method>/<kind>``. Message bodies
are JSON objects that the JSON-schema parsers of Foxglove and Lichtblick accept:
every field has one scalar type (``number``, ``integer``, ``string``) or is an object or
an array of one scalar type or of objects; no unions, no ``null``, no arrays of arrays.

Triggers, states and commands arrive in bulk; each MCAP message holds the **rows of
one window** (one trigger period by default: a small per-frame message) as an array
of row objects, one per delivery, each with its own send and receive time. In
Foxglove, ``/<method>/state.rows[:]{node==3}.z`` plots node 3 over time.

Values that may be missing are never ``null`` (see docs/concepts/recording.md):

* a row field whose value is not known or not finite is **absent** (``t_recv`` of a
  trigger issue or a command send; a non-finite state value);
* a command cell that is NaN ("keep the current setting") is written as ``0`` with
  ``valid[j] = 0`` (``valid[j] = 1``: ``values[j]`` is the command);
* a render sample's AoI of a node with nothing shown yet is ``-1`` (AoI is ≥ 0).

Aligned snapshots use Foxglove's ``foxglove.PosesInFrame`` in the z-up frame ``enu``
(x east, y north, z up; bodies forward-left-up), so the 3-D panel draws the swarm right
side up at its altitude; the NED states stay in the state channel. In ``incremental``
mode the poses are rounded to display precision (1 cm, quaternion 1e-4). In both modes
every snapshot also moves a frame to follow, ``<method>/swarm`` (child of ``enu`` at the
swarm's centre, ``foxglove.FrameTransform`` on ``/<method>/tf``).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["KINDS", "LEGACY", "READABLE", "SCHEMAS", "TABLE_KINDS", "schema_bytes"]

#: Message kinds, one channel each per method.
KINDS: tuple[str, ...] = ("trigger", "state", "command", "snapshot", "render", "tf")
#: Kinds listed by :func:`~sigma_des.record.reader.read_table` (``tf`` is derived from
#: the snapshots, for the viewers).
TABLE_KINDS: tuple[str, ...] = KINDS[:5]
#: Schema names of the column-batch layout written before (not read any more).
LEGACY: frozenset[str] = frozenset(
    {"sigma_des.Triggers", "sigma_des.States", "sigma_des.StateDeltas", "sigma_des.Commands"}
)

_NUM = {"type": "number"}
_INT = {"type": "integer"}


def _window(desc: str, row: dict[str, Any]) -> dict[str, Any]:
    """A window message: its end time and its rows."""
    return {
        "type": "object",
        "description": desc,
        "properties": {
            "t": {**_NUM, "description": "end of the window the rows were received in, s"},
            "rows": {"type": "array", "items": {"type": "object", "properties": row}},
        },
    }


_TIMES = {
    "node": {**_INT, "description": "node index (-1: the trigger's issue to every node)"},
    "frame": {**_INT, "description": "frame (trigger index) the message belongs to"},
    "t_send": {**_NUM, "description": "send (generation) time, s"},
    "t_recv": {**_NUM, "description": "receive time, s (absent: not known)"},
}
_POSE = {
    **{k: {**_NUM, "description": f"position {k.upper()}, NED m"} for k in ("x", "y", "z")},
    **{f"v{k}": {**_NUM, "description": f"velocity {k.upper()}, NED m/s"} for k in "xyz"},
    **{k: {**_NUM, "description": f"Euler angle {k}, rad"} for k in ("phi", "theta", "psi")},
}

_VEC3 = {
    "title": "foxglove.Vector3",
    "type": "object",
    "properties": {"x": _NUM, "y": _NUM, "z": _NUM},
    "required": ["x", "y", "z"],
}
_QUAT = {
    "title": "foxglove.Quaternion",
    "type": "object",
    "properties": {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM},
    "required": ["x", "y", "z", "w"],
}
_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
    },
}
_FRAME_TRANSFORM = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space (here: the frame "
    "that follows the swarm, named after the method, e.g. bides/swarm, child of enu, at the "
    "mean position of the snapshot's aircraft; no rotation)",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string", "description": "enu: x east, y north, z up (m)"},
        "child_frame_id": {"type": "string", "description": "the swarm frame, e.g. bides/swarm"},
        "translation": _VEC3,
        "rotation": _QUAT,
    },
    "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
}
_POSES_IN_FRAME = {
    "title": "foxglove.PosesInFrame",
    "description": "An array of timestamped poses for an object or reference frame in 3D space "
    "(here: the aligned snapshot of the swarm in frame enu; sigma_des adds frame, frames, "
    "nodes)",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string", "description": "enu: x east, y north, z up (m)"},
        "poses": {
            "type": "array",
            "items": {
                "title": "foxglove.Pose",
                "type": "object",
                "properties": {"position": _VEC3, "orientation": _QUAT},
                "required": ["position", "orientation"],
            },
        },
        "frame": {**_INT, "description": "aligned (reference) frame of the snapshot"},
        "frames": {"type": "array", "items": _INT, "description": "shown frame per node"},
        "nodes": {"type": "array", "items": _INT, "description": "node of each pose"},
    },
    "required": ["timestamp", "frame_id", "poses"],
}

#: ``(kind, record mode) -> (schema name, JSON schema)``.
SCHEMAS: dict[tuple[str, str], tuple[str, dict[str, Any]]] = {}
for _mode in ("full", "incremental"):
    SCHEMAS[("trigger", _mode)] = (
        "sigma_des.TriggerRows",
        _window("trigger deliveries (node -1 without t_recv: the trigger's issue)", _TIMES),
    )
    SCHEMAS[("command", _mode)] = (
        "sigma_des.CommandRows",
        _window(
            "behaviour commands delivered to nodes (frame: the alignment tick)",
            {
                **_TIMES,
                "values": {"type": "array", "items": _NUM,
                           "description": "command row; 0 where valid is 0"},
                "valid": {"type": "array", "items": _INT,
                          "description": "1: values[j] is set; 0: keep the current setting"},
            },
        ),
    )
    SCHEMAS[("tf", _mode)] = ("foxglove.FrameTransform", _FRAME_TRANSFORM)
    SCHEMAS[("render", _mode)] = (
        "sigma_des.Render",
        {
            "type": "object",
            "description": "one render sample: Age of Information per node",
            "properties": {
                "t": {**_NUM, "description": "render time, s"},
                "aoi": {"type": "array", "items": _NUM,
                        "description": "AoI per node, s (-1: nothing shown yet)"},
            },
        },
    )
SCHEMAS[("state", "full")] = (
    "sigma_des.StateRows",
    _window("node states delivered to the alignment server (absent value: not finite)",
            {**_TIMES, **_POSE}),
)
SCHEMAS[("state", "incremental")] = (
    "sigma_des.StateDeltaRows",
    _window(
        "node states, delta-encoded per node: rows with key=1 hold absolute values, "
        "others the change since the node's previous recorded row (in file order); states "
        "inside the dead-band are not recorded",
        {**_TIMES, "key": {"type": "integer", "enum": [0, 1]}, **_POSE},
    ),
)
SCHEMAS[("snapshot", "full")] = ("foxglove.PosesInFrame", _POSES_IN_FRAME)
SCHEMAS[("snapshot", "incremental")] = ("foxglove.PosesInFrame", _POSES_IN_FRAME)
#: Schema names written before and still read: incremental snapshots that held only the
#: frame per node (``t``, ``frame``, ``frames``).
READABLE: frozenset[str] = frozenset({"sigma_des.SnapshotFrames"})

def schema_bytes(kind: str, mode: str) -> tuple[str, bytes]:
    """Name and encoded JSON schema of ``kind`` in record ``mode``."""
    name, schema = SCHEMAS[(kind, mode)]
    return name, json.dumps(schema, sort_keys=True).encode()
