"""JSON schemas of the recorded channels (MCAP ``jsonschema`` encoding).

One channel per method and message kind, topic ``/<method>/<kind>``. Message bodies
are JSON objects; kinds that arrive in bulk (triggers, states, commands) are
*batches*: column arrays with one entry per recorded message, each entry carrying
its own send and receive time. Aligned snapshots in ``full`` mode use Foxglove's
well-known ``foxglove.PosesInFrame`` schema (so the swarm plays back in Foxglove's
3-D panel), extended with the frame fields a reader needs; in ``incremental`` mode a
snapshot stores only the frame of each node (its poses are in the state channel).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["KINDS", "SCHEMAS", "schema_bytes"]

#: Message kinds, one channel each per method.
KINDS: tuple[str, ...] = ("trigger", "state", "command", "snapshot", "render")

_NUM = {"type": "number"}
_INT = {"type": "integer"}


def _cols(desc: str, **cols: Any) -> dict[str, Any]:
    return {
        "type": "object",
        "description": desc,
        "properties": {
            "seq": {**_INT, "description": "batch sequence number within the channel"},
            **{k: {"type": "array", "items": v} for k, v in cols.items()},
        },
    }


_TIMES = {
    "node": {**_INT, "description": "node index (-1: broadcast to every node)"},
    "frame": {**_INT, "description": "frame (trigger index) the message belongs to"},
    "t_send": {**_NUM, "description": "send (generation) time, s"},
    "t_recv": {"type": ["number", "null"], "description": "receive time, s (null: not known)"},
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
}
_QUAT = {
    "title": "foxglove.Quaternion",
    "type": "object",
    "properties": {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM},
}
_POSES_IN_FRAME = {
    "title": "foxglove.PosesInFrame",
    "description": "An array of timestamped poses for an object or reference frame in 3D space "
    "(here: the aligned snapshot of the swarm; sigma_des adds frame and frames)",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "frame_id": {"type": "string"},
        "poses": {
            "type": "array",
            "items": {
                "title": "foxglove.Pose",
                "type": "object",
                "properties": {"position": _VEC3, "orientation": _QUAT},
            },
        },
        "frame": {**_INT, "description": "aligned (reference) frame of the snapshot"},
        "frames": {"type": "array", "items": _INT, "description": "shown frame per node"},
        "nodes": {"type": "array", "items": _INT, "description": "node of each pose"},
    },
}

#: ``(kind, record mode) -> (schema name, JSON schema)``.
SCHEMAS: dict[tuple[str, str], tuple[str, dict[str, Any]]] = {}
for _mode in ("full", "incremental"):
    SCHEMAS[("trigger", _mode)] = (
        "sigma_des.Triggers",
        _cols("trigger deliveries (node -1, t_recv null: trigger issued)", **_TIMES),
    )
    SCHEMAS[("command", _mode)] = (
        "sigma_des.Commands",
        _cols(
            "behaviour commands delivered to nodes (frame: the alignment tick)",
            **_TIMES,
            values={"type": "array", "items": _NUM},
        ),
    )
    SCHEMAS[("render", _mode)] = (
        "sigma_des.Render",
        {
            "type": "object",
            "description": "one render sample: Age of Information per node",
            "properties": {
                "t": {**_NUM, "description": "render time, s"},
                "aoi": {"type": "array", "items": {"type": ["number", "null"]}},
            },
        },
    )
SCHEMAS[("state", "full")] = (
    "sigma_des.States",
    _cols("node states delivered to the alignment server", **_TIMES, **_POSE),
)
SCHEMAS[("state", "incremental")] = (
    "sigma_des.StateDeltas",
    _cols(
        "node states, delta-encoded per node: rows with key=1 hold absolute values, "
        "others the change since the node's previous recorded row; states inside the "
        "dead-band are not recorded",
        **_TIMES,
        key={"type": "integer", "enum": [0, 1]},
        **_POSE,
    ),
)
SCHEMAS[("snapshot", "full")] = ("foxglove.PosesInFrame", _POSES_IN_FRAME)
SCHEMAS[("snapshot", "incremental")] = (
    "sigma_des.SnapshotFrames",
    {
        "type": "object",
        "description": "an aligned snapshot: the frame shown per node",
        "properties": {
            "t": _NUM,
            "frame": _INT,
            "frames": {"type": "array", "items": _INT},
        },
    },
)


def schema_bytes(kind: str, mode: str) -> tuple[str, bytes]:
    """Name and encoded JSON schema of ``kind`` in record ``mode``."""
    name, schema = SCHEMAS[(kind, mode)]
    return name, json.dumps(schema, sort_keys=True).encode()
