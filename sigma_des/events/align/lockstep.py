"""The ``lockstep`` method: a central barrier, trigger k+1 only after every live node's frame k.

docs/concepts/methods.md: after trigger k the server waits for the state
of frame k from every live node, re-requests a missing one every ``retry_timeout``
and, with ``eviction_timeout`` set, evicts nodes still missing after it (an evicted
node rejoins when it delivers the newest frame). The completed frame is the shown
snapshot; the engine issues the next trigger on :meth:`ServerContext.barrier_done`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sigma_des.core.flags import EXACT, EXTRAPOLATED, MISSING
from sigma_des.events.align.base import (
    OBS_WIDTH,
    RECORD_BYTES,
    Aligner,
    ServerContext,
    StateBatch,
)
from sigma_des.events.align.spec import AlignParams, LockstepSpec
from sigma_des.metrics.reports import AlignerReport

__all__ = ["Barrier", "LockstepAligner"]


class Barrier(NamedTuple):
    """The barrier's state (what the compiled core mirrors before it runs messages).

    Attributes:
        got: per node, its state of ``current`` has arrived.
        live: nodes the barrier waits for (not evicted).
        current: the frame the barrier waits for (-1 before the first trigger).
        missing: live nodes whose state of ``current`` is still missing.
        complete: the barrier of ``current`` is done.
    """

    got: NDArray[np.bool_]
    live: NDArray[np.bool_]
    current: int
    missing: int
    complete: bool


@njit(cache=True)
def count_rows(nodes: NDArray[np.int64], frames: NDArray[np.int64],  # pragma: no cover
               gens: NDArray[np.float64], obs: NDArray[np.float64], start: int,
               current: int, complete: bool, missing: int, live: NDArray[np.bool_],
               got: NDArray[np.bool_], gen: NDArray[np.float64],
               obs_out: NDArray[np.float64]) -> tuple[int, int, int]:
    """Count the barrier's states from row ``start`` on, until a row completes it.

    The rule of :meth:`LockstepAligner.on_states` row by row, compiled: an evicted node
    delivering ``current`` rejoins (``live``, one more missing); a row of ``current``
    not yet counted, while the barrier waits, is stored (``got``, ``gen``, ``obs_out``)
    and counted. Stops at the row that leaves no state missing, so that the caller
    completes the barrier (and the engine may open the next one) before the later rows.

    Returns:
        ``(row that completed the barrier or -1, missing, rejoined nodes)``.
    """
    rejoined = 0
    for j in range(start, nodes.size):
        node = nodes[j]
        frame = frames[j]
        if not live[node] and frame == current:
            live[node] = True
            rejoined += 1
            missing += 1
        if frame != current or complete or got[node]:
            continue
        missing -= 1
        got[node] = True
        gen[node] = gens[j]
        obs_out[node, :] = obs[j, :]
        if missing <= 0:
            return j, missing, rejoined
    return -1, missing, rejoined


class LockstepAligner(Aligner):
    """Central barrier: trigger k+1 only after every live node's state of frame k.

    Args:
        n: number of nodes.
        spec: retry and eviction timeouts.
        ctx: the engine's side of the server.

    Attributes:
        live: nodes the barrier waits for (not evicted).
        current: the frame the barrier waits for (-1 before the first trigger).
        complete: the barrier of :attr:`current` is done.
        got: per node, its state of :attr:`current` has arrived.
        missing: live nodes whose state of :attr:`current` is still missing.
    """

    name = "lockstep"

    def __init__(self, n: int, spec: LockstepSpec, ctx: ServerContext) -> None:
        super().__init__(n, ctx)
        self.spec = spec
        self.live = np.ones(n, dtype=np.bool_)
        self.current = -1
        self.complete = True
        self.got = np.zeros(n, dtype=np.bool_)
        self._gen = np.full(n, np.nan)
        self._obs = np.full((n, OBS_WIDTH), np.nan)
        self._done_frame = -1
        self._done_gen = np.full(n, np.nan)
        self._done_obs = np.full((n, OBS_WIDTH), np.nan)
        self._done_has = np.zeros(n, dtype=np.bool_)
        self._dirty = False
        self.evicted = 0
        self.rejoined = 0
        self.rerequests = 0
        self.missing = 0

    @classmethod
    def build(cls, n: int, ctx: ServerContext, params: AlignParams) -> LockstepAligner:
        """The registry's constructor: ``params.lockstep``."""
        return cls(n, params.lockstep, ctx)

    def on_trigger(self, frame: int, t: float) -> None:
        """Open the barrier of ``frame`` and arm its retry and eviction timers."""
        self.current = frame
        self.complete = False
        self.got[:] = False
        self.missing = int(self.live.sum())  # a counter: O(1) per arrival, not O(n)
        spec = self.spec
        self.ctx.call_at(t + spec.retry_timeout, self._retry, frame, 1)
        if spec.eviction_timeout > 0:
            self.ctx.call_at(t + spec.eviction_timeout, self._evict, frame)

    def on_states(self, batch: StateBatch) -> None:
        """Count the barrier's states row by row (:func:`count_rows`, compiled): an
        evicted node that has caught up (delivers the newest frame) rejoins, counting
        from this frame if the barrier still waits, else from the next one; a row may
        complete the barrier mid-batch, and the rows after it meet the next one if the
        engine opened it meanwhile."""
        nodes, frames, gens, obs = batch.nodes, batch.frames, batch.gens, batch.obs
        j = 0
        while j < nodes.size:
            k, self.missing, rejoined = count_rows(
                nodes, frames, gens, obs, j, self.current, self.complete, self.missing,
                self.live, self.got, self._gen, self._obs)
            self.rejoined += rejoined
            if k < 0:
                return
            self._check_complete()
            j = k + 1

    def _check_complete(self) -> None:
        if self.complete or self.missing > 0:
            return
        self.complete = True
        got = self.got
        self._done_frame = self.current
        self._done_gen[got] = self._gen[got]
        self._done_obs[got] = self._obs[got]
        self._done_has |= got
        self._dirty = True
        self.ctx.barrier_done(self.current)

    def _retry(self, frame: int, retry: int) -> None:
        if frame != self.current or self.complete:
            return
        missing = np.flatnonzero(self.live & ~self.got)
        for node in missing.tolist():
            self.rerequests += 1
            self.ctx.rerequest(node, frame, retry)
        self.ctx.call_at(self.ctx.now() + self.spec.retry_timeout, self._retry, frame, retry + 1)

    def _evict(self, frame: int) -> None:
        if frame != self.current or self.complete:
            return
        missing = self.live & ~self.got
        self.evicted += int(missing.sum())
        self.live &= ~missing
        self.missing = 0
        self._check_complete()

    def align(self, t: float) -> None:
        """Show the last completed frame (an evicted node keeps its last state, EXTRAPOLATED)."""
        self.new_snapshot = self._dirty
        if self._dirty:
            has = self._done_has
            fresh = has & self.live
            self.shown_gen[has] = self._done_gen[has]
            self.shown_obs[has] = self._done_obs[has]
            # the shown frame of an evicted node stays at its last completed frame
            self.shown_frame[fresh] = self._done_frame
            self.flag[:] = np.where(fresh, EXACT, np.where(has, EXTRAPOLATED, MISSING))
            self.aligned_frame = self._done_frame
            self._dirty = False
        self.note_memory()

    def memory_bytes(self) -> int:
        """The frame being collected and the completed one."""
        return 2 * self.n * RECORD_BYTES

    def barrier(self) -> Barrier:
        """The barrier's state now (its arrays are the aligner's own: read, do not write)."""
        return Barrier(self.got, self.live, self.current, self.missing, self.complete)

    def report(self) -> AlignerReport:
        """Peak memory, evictions, rejoins and re-requests."""
        return AlignerReport(
            peak_bytes=self.peak_bytes,
            evicted=self.evicted,
            rejoined=self.rejoined,
            rerequests=self.rerequests,
        )
