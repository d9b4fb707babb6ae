"""Aligned snapshots as ``foxglove.PosesInFrame`` in the z-up frame ``enu``, and the
frame ``<method>/swarm`` that follows them (``foxglove.FrameTransform``).

The simulator's poses are NED (x north, y east, z down) with Z-Y-X Euler angles of a
forward-right-down body. A viewer's world is z-up, so the snapshot is written in
``enu`` (x east, y north, z up) with forward-left-up bodies — the ROS convention
(REP 103) — and the 3-D panel draws the swarm right side up at its altitude:
``position.z`` is the altitude. Both changes of axes are rotations by π
(NED → ENU: ``R_z(π/2)·R_x(π)``; FLU → FRD: ``R_x(π)``), so nothing is mirrored, and
moving them through the Z-Y-X Euler product gives the ENU attitude of a FLU body in one
SciPy call: ``R_z(π/2 − ψ)·R_y(−θ)·R_x(φ)`` (heading measured from east, pitch sign
flipped with the y axis, roll unchanged).

The swarm frame's origin is the mean ENU position of the snapshot's nodes whose
position is finite, with no rotation (its axes stay east, north, up): a 3-D panel whose
display frame it is, in follow mode *Position*, keeps the aircraft in view.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

__all__ = ["FRAME_ID", "enu_poses", "poses_in_frame", "stamp", "swarm_frame",
           "swarm_transform"]

#: ``frame_id`` of the snapshots.
FRAME_ID = "enu"


def swarm_frame(method: str) -> str:
    """The frame that follows ``method``'s swarm: ``<method>/swarm``."""
    return f"{method}/swarm"


def stamp(t: float) -> dict[str, int]:
    """Foxglove's ``time`` (``sec``, ``nsec``) of ``t`` seconds (negative: 0)."""
    ts = max(t, 0.0)
    sec = int(ts)
    return {"sec": sec, "nsec": min(999_999_999, max(0, round((ts - sec) * 1e9)))}


def enu_poses(pos: NDArray[np.float64], att: NDArray[np.float64] | None
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ENU positions and FLU-body → ENU quaternions ``(x, y, z, w)`` of NED poses.

    Args:
        pos: ``(n, 3)`` NED positions (m).
        att: ``(n, 3)`` Euler angles ``(phi, theta, psi)`` (rad, Z-Y-X), or None (level,
            heading north).
    """
    n = pos.shape[0]
    p = np.stack([pos[:, 1], pos[:, 0], -pos[:, 2]], axis=1)
    a = np.zeros((n, 3)) if att is None else att
    q = np.full((n, 4), np.nan)
    ok = np.isfinite(a).all(axis=1)
    if ok.any():
        phi, theta, psi = a[ok].T
        enu = np.stack([np.pi / 2 - psi, -theta, phi], axis=1)
        q[ok] = Rotation.from_euler("ZYX", enu).as_quat(canonical=True)  # w >= 0
    return p, q


def poses_in_frame(t: float, frame: int, frames: NDArray[np.int64], pos: NDArray[np.float64],
                   att: ArrayLike | None, decimals: tuple[int, int] | None = None
                   ) -> dict[str, Any]:
    """A ``foxglove.PosesInFrame`` body with sigma_des's frame fields added.

    Nodes whose position or attitude is not finite have no pose; ``nodes`` names the
    node of each pose. ``decimals``: round positions and quaternions to these many
    decimal places (None: exact).
    """
    n = frames.size
    a = None if att is None else np.asarray(att, dtype=float).reshape(n, 3)
    p, q = enu_poses(pos.reshape(n, 3), a)
    if decimals is not None:
        p, q = np.round(p, decimals[0]), np.round(q, decimals[1])
    ok = np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1)
    poses = [
        {
            "position": {"x": u[0], "y": u[1], "z": u[2]},
            "orientation": {"x": v[0], "y": v[1], "z": v[2], "w": v[3]},
        }
        for u, v in zip(p[ok].tolist(), q[ok].tolist(), strict=True)
    ]
    return {
        "timestamp": stamp(t),
        "frame_id": FRAME_ID,
        "poses": poses,
        "frame": frame,
        "frames": np.ascontiguousarray(frames, dtype=np.int64),
        "nodes": np.flatnonzero(ok).astype(np.int64),
    }


def swarm_transform(t: float, method: str, pos: NDArray[np.float64]) -> dict[str, Any] | None:
    """The ``foxglove.FrameTransform`` of ``<method>/swarm`` at ``t``, or None.

    Args:
        t: the snapshot's time (s).
        method: the method (names the frame).
        pos: ``(n, 3)`` NED positions (m); rows that are not finite are left out.

    Returns:
        The transform from ``enu`` to the swarm frame at the mean ENU position of the
        finite rows (identity rotation); None if no row is finite.
    """
    p = pos.reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if p.shape[0] == 0:
        return None
    north, east, down = (float(v) for v in p.mean(axis=0))
    return {
        "timestamp": stamp(t),
        "parent_frame_id": FRAME_ID,
        "child_frame_id": swarm_frame(method),
        "translation": {"x": east, "y": north, "z": -down},
        "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
    }
