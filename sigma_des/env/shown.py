"""What a step of the vector env reads of its scenes, gathered once into arrays.

A step of :class:`~sigma_des.env.vector.SwarmVec` reads every live scene's view of its
command tick three times: to observe it (the end of a step), to report its ages and
frames (the infos) and to turn the next actions into commands (the start of the next
step). Nothing runs between those reads: the scene pauses at its command tick until
its commands are published. :class:`Shown` gathers the views of a set of scenes into
``(S, n, ...)`` arrays once, keyed by the identity of each scene's captured view (a new
object at each command tick, and a restarted scene is a new scene with a new capture),
so a later read of the same views reuses them, a subset by row.

:func:`truths` is the true published state of a set of scenes: one call of the
model's ``observe`` over all their states when the model says its rows are
independent (``observe_rows``, as ``frame_free`` says it of ``step``), else one call per
scene; the same bits either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import DynamicsModel
from sigma_des.env.scenes import Scene

__all__ = ["Shown", "truths"]

Array = NDArray[np.float64]


def truths(scenes: Sequence[Scene], dyn: DynamicsModel) -> Array:
    """``(len(scenes), n, 12)`` true published states (:meth:`Scene.truth` of each).

    A model with ``observe_rows`` (its ``observe`` maps each row alone, with the same
    operations whatever rows share the call) observes the scenes' states stacked in
    one call; any other model is called once per scene.
    """
    if len(scenes) > 1 and getattr(dyn, "observe_rows", False):
        states = [sc.run.truth.state for sc in scenes]
        n = states[0].shape[0]
        return dyn.observe(np.concatenate(states)).reshape(len(scenes), n, -1)
    return np.stack([sc.truth() for sc in scenes])


class Shown:
    """The views of scenes ``ids`` at their current command tick, as arrays.

    Attributes:
        ids: the scenes' indices.
        keys: each scene's captured view (what identifies its command tick).
        obs: ``(S, n, 12)`` shown states (the true ones under perfect information).
        valid: ``(S, n)`` nodes with a shown state (all under perfect information).
        frame: ``(S, n)`` frames of the shown states (of the captured views).
        gen: ``(S, n)`` generation times of the shown states (NaN where none).
        t: ``(S,)`` simulated times (s).
        eps: the scenes' episode data.
    """

    __slots__ = ("eps", "frame", "gen", "ids", "keys", "obs", "rows", "t", "valid")

    def __init__(self, ids: list[int], keys: list[Any], obs: Array, valid: NDArray[np.bool_],
                 frame: NDArray[np.int64], gen: Array, t: Array, eps: list[Any]) -> None:
        self.ids, self.keys = ids, keys
        self.obs, self.valid, self.frame, self.gen, self.t, self.eps = (obs, valid, frame,
                                                                        gen, t, eps)
        self.rows = {s: r for r, s in enumerate(ids)}

    @classmethod
    def gather(cls, scenes: Sequence[Scene], ids: list[int], dyn: DynamicsModel,
               perfect: bool) -> Shown:
        """The views of scenes ``ids`` (each captured), gathered: their shown states, or
        under ``perfect`` information their true states, every node valid."""
        picked = [scenes[s] for s in ids]
        keys = [sc.view for sc in picked]
        # np.array of a list of equal-shape arrays: np.stack's copy, in one C call
        if perfect:
            obs = truths(picked, dyn)
            valid = np.ones(obs.shape[:2], dtype=bool)
        else:
            obs = np.array([v.obs for v in keys])
            valid = np.array([v.valid for v in keys])
        return cls(ids, keys, obs, valid, np.array([v.frame for v in keys]),
                   np.array([sc.run.aligner.shown_gen for sc in picked]),
                   np.array([sc.run.kernel.now for sc in picked]), [sc.ep for sc in picked])

    def of(self, scenes: Sequence[Scene], ids: list[int]) -> Shown | None:
        """These views restricted to scenes ``ids`` if every one of them is still at the
        command tick gathered here (None: one is not, or was not gathered)."""
        if ids == self.ids:
            return self if self._current(scenes, ids, self.keys) else None
        rows: list[int] = []
        for s in ids:
            r = self.rows.get(s)
            if r is None:
                return None
            rows.append(r)
        keys = [self.keys[r] for r in rows]
        if not self._current(scenes, ids, keys):
            return None
        return Shown(ids, keys, self.obs[rows], self.valid[rows], self.frame[rows],
                     self.gen[rows], self.t[rows], [self.eps[r] for r in rows])

    @staticmethod
    def _current(scenes: Sequence[Scene], ids: list[int], keys: list[Any]) -> bool:
        """Whether each scene of ``ids`` still holds the captured view of ``keys``."""
        for s, key in zip(ids, keys, strict=True):
            if key is None or scenes[s].capture.view is not key:
                return False
        return True
