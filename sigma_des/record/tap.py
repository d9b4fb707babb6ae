"""The engines' recording tap: turns engine-side events into recorder calls.

An engine run with a tap attached (``MethodRun.record``) calls it where messages are
delivered, snapshots change and render ticks sample. Both engines call it in
simulated-time order, and states reach it no later than the next tick, so at an
alignment or render tick at ``t`` (one every 0.2 s of simulated time at most) the tap
promises the recorder that nothing older than ``t`` follows
(:meth:`~sigma_des.record.method.MethodRecorder.advance`): the recording is written as
the run goes, in ``log_time`` order, one message per trigger period and channel. The
tap converts the published state rows (columns
:data:`~sigma_des.core.models.OBS_FIELDS`: body velocities, Euler angles, body rates,
north/east position, altitude up) to NED position, NED velocity and Euler angles, and
writes them through a :class:`~sigma_des.record.method.MethodRecorder`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.tap import Tap
from sigma_des.record.method import MethodRecorder
from sigma_des.record.writer import Recorder

__all__ = ["RecordTap", "obs_to_ned"]

_F = NDArray[np.float64]
_CONVERT_EVERY = 4096  # states converted to NED in batches of about this many
_ADVANCE_EVERY = 0.2  # s of simulated time between promises (fewer, larger writes)


def obs_to_ned(obs: _F) -> tuple[_F, _F, _F]:
    """NED position, NED velocity and Euler angles of ``(m, 12)`` published states."""
    uvw = obs[:, 0:3]
    phi, th, psi = obs[:, 3], obs[:, 4], obs[:, 5]
    cp, sp, ct, st = np.cos(phi), np.sin(phi), np.cos(th), np.sin(th)
    cs, ss = np.cos(psi), np.sin(psi)
    # body -> NED rotation of Z-Y-X Euler angles, rows applied to (u, v, w)
    r = np.stack(
        [
            np.stack([ct * cs, sp * st * cs - cp * ss, cp * st * cs + sp * ss], axis=1),
            np.stack([ct * ss, sp * st * ss + cp * cs, cp * st * ss - sp * cs], axis=1),
            np.stack([-st, sp * ct, cp * ct], axis=1),
        ],
        axis=1,
    )
    vel = np.einsum("mij,mj->mi", r, uvw)
    pos = np.stack([obs[:, 9], obs[:, 10], -obs[:, 11]], axis=1)
    return pos, vel, obs[:, 3:6].copy()


class RecordTap(Tap):
    """Records one method run into its own MCAP file.

    Args:
        path: the file (replaced if it exists).
        scenario: scenario dict stored in the file.
        method: the method.
        spec: record settings (``mode``, dead-bands, ``keyframe_every``).
    """

    def __init__(self, path: str | Path, scenario: dict[str, Any], method: str, spec: Any) -> None:
        f_trig = float(scenario.get("f_trig", 100.0))
        self.rec = Recorder(
            path,
            scenario=scenario,
            mode=spec.mode,
            deadband_pos=spec.deadband_pos,
            deadband_vel=spec.deadband_vel,
            deadband_att=spec.deadband_att,
            keyframe_every=spec.keyframe_every,
            window=1.0 / f_trig,
        )
        self.run: MethodRecorder = self.rec.run(method, mode="des")
        self._pending: list[tuple[_F, NDArray[np.int64], NDArray[np.int64], _F, _F]] = []
        self._n_pending = 0
        self._advanced = -math.inf

    def trigger(self, node: int, frame: int, t_send: float, t_recv: float) -> None:
        """A trigger delivery (node -1 and NaN receive time: the trigger's issue)."""
        self.run.trigger(frame=frame, node=node, t_send=t_send, t_recv=t_recv)

    def states(self, t_recv: _F, nodes: NDArray[np.int64], frames: NDArray[np.int64],
               gens: _F, obs: _F) -> None:
        """State deliveries to the server, in arrival order (converted in batches)."""
        self._pending.append((np.array(t_recv, dtype=float), np.array(nodes, dtype=np.int64),
                              np.array(frames, dtype=np.int64), np.array(gens, dtype=float),
                              np.array(obs, dtype=float).reshape(-1, obs.shape[-1])))
        self._n_pending += self._pending[-1][1].size
        if self._n_pending >= _CONVERT_EVERY:
            self._states_now()

    def _states_now(self) -> None:
        if not self._pending:
            return
        tr, nd, fr, gen, obs = (np.concatenate(c) for c in zip(*self._pending, strict=True))
        self._pending = []
        self._n_pending = 0
        pos, vel, att = obs_to_ned(obs)
        self.run.states(nd, fr, gen, tr, np.concatenate([pos, vel, att], axis=1))

    def commands(self, nodes: NDArray[np.int64], tick: int, t_send: float, t_recv: _F,
                 rows: _F) -> None:
        """Command deliveries (or sends, with NaN receive times) of alignment tick ``tick``."""
        m = nodes.size
        self.run.commands(nodes, np.full(m, tick), np.full(m, t_send), t_recv, rows)

    def snapshot(self, t: float, frame: int, frames: NDArray[np.int64], obs: _F) -> None:
        """A new aligned snapshot shown at ``t``."""
        self._advance(t)
        pos, _vel, att = obs_to_ned(obs)
        self.run.snapshot(t=t, frame=frame, frames=frames, pos=pos, att=att)

    def render(self, t: float, gen: _F) -> None:
        """A render tick: AoI per node (NaN where nothing is shown)."""
        self._advance(t)
        self.run.render(t=t, aoi=t - gen)

    def _advance(self, t: float) -> None:
        """A tick at ``t``: every state received so far is handed over, then written.

        Only every ``_ADVANCE_EVERY`` s: the file is the same (windows are whole when
        written), the recorder's per-write work is paid less often.
        """
        if t - self._advanced < _ADVANCE_EVERY:
            return
        self._advanced = t
        self._states_now()
        self.run.advance(t)

    def close(self) -> None:
        """Finish the file."""
        self._states_now()
        self.rec.close()
