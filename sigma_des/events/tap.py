"""The recording tap seam: where a run hands what happens to a recording.

A run calls its tap where messages are delivered, snapshots change and render
ticks sample (:meth:`~sigma_des.events.engine.MethodRun.record` attaches one).
Without a recording the tap is the base :class:`Tap`, whose hooks do nothing (a
null object), so the engine and the compiled core call their tap unconditionally;
:class:`sigma_des.record.tap.RecordTap` overrides them to write an MCAP file.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["Tap", "records"]

_F = NDArray[np.float64]


class Tap:
    """A run's recording tap; this base records nothing (every hook returns at once).

    A recording overrides the hooks (:class:`sigma_des.record.tap.RecordTap`). Rows
    are published states (columns :data:`~sigma_des.core.models.OBS_FIELDS`).
    """

    def trigger(self, node: int, frame: int, t_send: float, t_recv: float) -> None:
        """A trigger delivery (node -1 and NaN receive time: the trigger's issue)."""

    def issue(self, frame: int, t_send: float) -> None:
        """Trigger ``frame`` is issued at ``t_send`` (both engines call it, whatever
        they record through :meth:`trigger`: the per-message engine each delivery, the
        compiled core the issue)."""

    def states(self, t_recv: _F, nodes: NDArray[np.int64], frames: NDArray[np.int64],
               gens: _F, obs: _F) -> None:
        """State deliveries to the server, in arrival order."""

    def commands(self, nodes: NDArray[np.int64], tick: int, t_send: float, t_recv: _F,
                 rows: _F) -> None:
        """Command deliveries (or sends, with NaN receive times) of alignment tick ``tick``."""

    def snapshot(self, t: float, frame: int, frames: NDArray[np.int64], obs: _F) -> None:
        """A new aligned snapshot shown at ``t``."""

    def render(self, t: float, gen: _F) -> None:
        """A render tick: what is shown, by generation time."""

    def close(self) -> None:
        """The run ended."""


def records(tap: Tap, hook: str) -> bool:
    """Whether ``tap`` overrides ``hook`` (e.g. ``"commands"``): a caller may skip building
    the arguments of a hook the base :class:`Tap` would ignore."""
    return getattr(type(tap), hook, None) is not getattr(Tap, hook)
