"""The four alignment methods (DESIGN §3) behind one small interface.

An aligner lives at the alignment server. The engine hands it every delivered
state (:meth:`Aligner.on_state`), tells it when a trigger is issued
(:meth:`Aligner.on_trigger`) and, at every alignment tick, asks it to refresh
the snapshot it shows (:meth:`Aligner.align`): per node the frame, generation
time, published state and a flag. Methods that steer the trigger (Lock-Step's
barrier, BiDES's adaptive rate) do so through the :class:`ServerContext` the
engine passes in. Pick one by name from :data:`ALIGNERS`.
"""

from __future__ import annotations

import typing
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.config import Scenario
from sigma_des.events.bides_align import EXACT, EXTRAPOLATED, MISSING, RingBuffers, align
from sigma_des.events.hlc import BatchStabilityBuffer, StabilityBuffer, Stamp

__all__ = [
    "ALIGNERS",
    "Aligner",
    "BidesAligner",
    "HLCAligner",
    "LockstepAligner",
    "NoneAligner",
    "ServerContext",
    "OBS_WIDTH",
]

OBS_WIDTH = 12
_Record = tuple[int, float, NDArray[np.float64]]  # (frame, generation time, obs)
_RECORD_BYTES = OBS_WIDTH * 8 + 8 + 8  # obs + frame + generation time


def newest_rows(
    nodes: NDArray[np.int64], frames: NDArray[np.int64], current: NDArray[np.int64]
) -> NDArray[np.intp]:
    """Rows a one-by-one "take it if its frame beats the node's current" loop keeps.

    Going through the rows in order, a row replaces its node's entry when its frame
    is greater than the entry's; what remains is, per node, the first row with the
    node's highest frame in the batch, if that frame beats ``current[node]``.

    Returns:
        Indices of those rows (at most one per node).
    """
    order = np.lexsort((np.arange(nodes.size), -frames, nodes))
    first = np.ones(order.size, dtype=np.bool_)
    first[1:] = nodes[order[1:]] != nodes[order[:-1]]
    best = order[first]
    return best[frames[best] > current[nodes[best]]]


class ServerContext(Protocol):
    """What an aligner may ask of the engine (trigger source and scheduler)."""

    @property
    def latest_trigger(self) -> int:
        """Index of the newest trigger issued."""
        ...

    @property
    def f_trig(self) -> float:
        """The current trigger rate (Hz)."""
        ...

    def now(self) -> float:
        """Current simulated time."""
        ...

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        """Schedule ``fn(*args)`` at time ``t``."""
        ...

    def set_rate(self, f_trig: float) -> None:
        """Change the trigger frequency from the next trigger on."""
        ...

    def barrier_done(self, frame: int) -> None:
        """Lock-Step: every live node's state of ``frame`` has arrived."""
        ...

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: ask ``node`` again for its state of ``frame``."""
        ...


class Aligner:
    """Base class: the shown snapshot and no-op hooks.

    Attributes:
        shown_frame: frame of the state shown per node (-1: none).
        shown_gen: generation time of the shown state (NaN: none).
        shown_obs: ``(n, 12)`` shown published states.
        flag: per node EXACT/FILLED/EXTRAPOLATED/MISSING.
        aligned_frame: the snapshot's reference frame (-1 before any).
        new_snapshot: set by :meth:`align` when the snapshot advanced.
    """

    name = "base"

    def __init__(self, n: int, sc: Scenario, ctx: ServerContext) -> None:
        self.n = n
        self.sc = sc
        self.ctx = ctx
        self.shown_frame = np.full(n, -1, dtype=np.int64)
        self.shown_gen = np.full(n, np.nan)
        self.shown_obs = np.full((n, OBS_WIDTH), np.nan)
        self.flag = np.full(n, MISSING, dtype=np.uint8)
        self.aligned_frame = -1
        self.new_snapshot = False
        self.peak_bytes = 0

    def on_trigger(self, frame: int, t: float) -> None:
        """A trigger for ``frame`` was issued at ``t``."""

    def on_state(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None,
    ) -> None:
        """A state of ``node`` for ``frame`` (generated at ``gen``) arrived at ``t``."""
        raise NotImplementedError

    def on_states(
        self,
        t: NDArray[np.float64],
        nodes: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
        hlc_l: NDArray[np.float64],
        hlc_c: NDArray[np.int64],
    ) -> None:
        """A batch of :meth:`on_state` calls, in arrival order (the cohort engine's path).

        Subclasses override it with a vectorised equivalent; ``hlc_l``/``hlc_c`` are
        the stamps' parts (meaningful for HLC only).
        """
        for j in range(nodes.size):
            self.on_state(
                float(t[j]), int(nodes[j]), int(frames[j]), float(gens[j]), obs[j].copy(), None
            )

    def align(self, t: float) -> None:
        """Refresh the shown snapshot (alignment tick)."""
        raise NotImplementedError

    def memory_bytes(self) -> int:
        """Bytes of state buffered by the alignment server now."""
        return self.n * _RECORD_BYTES

    def _note_memory(self) -> None:
        self.peak_bytes = max(self.peak_bytes, self.memory_bytes())


class NoneAligner(Aligner):
    """No alignment: each node's newest received state, whatever its frame."""

    name = "none"

    def __init__(self, n: int, sc: Scenario, ctx: ServerContext) -> None:
        super().__init__(n, sc, ctx)
        self._frame = np.full(n, -1, dtype=np.int64)
        self._gen = np.full(n, np.nan)
        self._obs = np.full((n, OBS_WIDTH), np.nan)
        self._dirty = False

    def on_state(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None,
    ) -> None:
        if frame > self._frame[node]:
            self._frame[node] = frame
            self._gen[node] = gen
            self._obs[node] = obs
            self._dirty = True

    def on_states(
        self,
        t: NDArray[np.float64],
        nodes: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
        hlc_l: NDArray[np.float64],
        hlc_c: NDArray[np.int64],
    ) -> None:
        win = newest_rows(nodes, frames, self._frame)
        if win.size:
            nd = nodes[win]
            self._frame[nd] = frames[win]
            self._gen[nd] = gens[win]
            self._obs[nd] = obs[win]
            self._dirty = True

    def align(self, t: float) -> None:
        self.new_snapshot = self._dirty
        if self._dirty:
            self.shown_frame[:] = self._frame
            self.shown_gen[:] = self._gen
            self.shown_obs[:] = self._obs
            self.flag[:] = np.where(self._frame >= 0, EXACT, MISSING)
            self.aligned_frame = int(self._frame.max())
            self._dirty = False
        self._note_memory()


class LockstepAligner(Aligner):
    """Central barrier: trigger k+1 only after every live node's state of frame k."""

    name = "lockstep"

    def __init__(self, n: int, sc: Scenario, ctx: ServerContext) -> None:
        super().__init__(n, sc, ctx)
        self.live = np.ones(n, dtype=np.bool_)
        self.current = -1
        self.complete = True
        self._got = np.zeros(n, dtype=np.bool_)
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
        self._missing = 0

    def on_trigger(self, frame: int, t: float) -> None:
        self.current = frame
        self.complete = False
        self._got[:] = False
        self._missing = int(self.live.sum())  # a counter: O(1) per arrival, not O(n)
        spec = self.sc.lockstep
        self.ctx.call_at(t + spec.retry_timeout, self._retry, frame, 1)
        if spec.eviction_timeout > 0:
            self.ctx.call_at(t + spec.eviction_timeout, self._evict, frame)

    def on_state(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None,
    ) -> None:
        if not self.live[node] and frame == self.current:
            # an evicted node that has caught up (delivers the newest frame) rejoins; it
            # counts from this frame if the barrier still waits, else from the next one
            self.live[node] = True
            self.rejoined += 1
            self._missing += 1
        if frame != self.current or self.complete or self._got[node]:
            return
        self._missing -= 1
        self._got[node] = True
        self._gen[node] = gen
        self._obs[node] = obs
        self._check_complete()

    def _check_complete(self) -> None:
        if self.complete or self._missing > 0:
            return
        self.complete = True
        got = self._got
        self._done_frame = self.current
        self._done_gen[got] = self._gen[got]
        self._done_obs[got] = self._obs[got]
        self._done_has |= got
        self._dirty = True
        self.ctx.barrier_done(self.current)

    def _retry(self, frame: int, retry: int) -> None:
        if frame != self.current or self.complete:
            return
        missing = np.flatnonzero(self.live & ~self._got)
        for node in missing.tolist():
            self.rerequests += 1
            self.ctx.rerequest(node, frame, retry)
        self.ctx.call_at(
            self.ctx.now() + self.sc.lockstep.retry_timeout, self._retry, frame, retry + 1
        )

    def _evict(self, frame: int) -> None:
        if frame != self.current or self.complete:
            return
        missing = self.live & ~self._got
        self.evicted += int(missing.sum())
        self.live &= ~missing
        self._missing = 0
        self._check_complete()

    def align(self, t: float) -> None:
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
        self._note_memory()

    def memory_bytes(self) -> int:
        return 2 * self.n * _RECORD_BYTES


class HLCAligner(Aligner):
    """Hybrid logical clocks: states shown in HLC order once causally stable."""

    name = "hlc"

    def __init__(self, n: int, sc: Scenario, ctx: ServerContext) -> None:
        super().__init__(n, sc, ctx)
        self.buffer: StabilityBuffer | BatchStabilityBuffer = StabilityBuffer(n)
        self._heard = np.zeros(n)
        self._live = np.ones(n, dtype=np.bool_)

    def on_state(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None,
    ) -> None:
        assert stamp is not None, "HLC states must carry a stamp"
        if not isinstance(self.buffer, StabilityBuffer):
            raise RuntimeError("an HLC aligner takes either single states or batches")
        self.buffer.add(node, stamp, (frame, gen, obs))
        self._heard[node] = t
        if not self._live[node]:
            self._live[node] = True
            self.buffer.set_live(node, True)

    def on_states(
        self,
        t: NDArray[np.float64],
        nodes: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
        hlc_l: NDArray[np.float64],
        hlc_c: NDArray[np.int64],
    ) -> None:
        buf = self.buffer
        if not isinstance(buf, BatchStabilityBuffer):
            if len(buf) or buf._has.any():
                raise RuntimeError("an HLC aligner takes either single states or batches")
            self.buffer = buf = BatchStabilityBuffer(self.n, OBS_WIDTH)
            buf._live[:] = self._live
        buf.add_many(nodes, hlc_l, hlc_c, frames, gens, obs)
        # arrival times never decrease, so the newest per node is the largest
        np.maximum.at(self._heard, nodes, t)
        back = np.unique(nodes[~self._live[nodes]])
        for node in back.tolist():
            self._live[node] = True
            buf.set_live(node, True)

    def align(self, t: float) -> None:
        timeout = self.sc.hlc.liveness_timeout
        if timeout > 0:
            dead = self._live & (self._heard < t - timeout)
            for node in np.flatnonzero(dead).tolist():
                self._live[node] = False
                self.buffer.set_live(node, False)
        self._note_memory()
        if isinstance(self.buffer, BatchStabilityBuffer):
            self._release_batch()
            return
        changed = False
        for _stamp, node, item in self.buffer.release():
            frame, gen, obs = typing.cast(_Record, item)
            if frame > self.shown_frame[node]:
                self.shown_frame[node] = frame
                self.shown_gen[node] = gen
                self.shown_obs[node] = obs
                self.flag[node] = EXACT
                changed = True
        self.new_snapshot = changed
        if changed:
            self.aligned_frame = int(self.shown_frame.max())

    def _release_batch(self) -> None:
        """The release loop of :meth:`align`, vectorised (same result, same order rule)."""
        assert isinstance(self.buffer, BatchStabilityBuffer)
        nodes, frames, gens, obs = self.buffer.release_arrays()
        changed = False
        if nodes.size:
            win = newest_rows(nodes, frames, self.shown_frame)
            if win.size:
                nd = nodes[win]
                self.shown_frame[nd] = frames[win]
                self.shown_gen[nd] = gens[win]
                self.shown_obs[nd] = obs[win]
                self.flag[nd] = EXACT
                changed = True
        self.new_snapshot = changed
        if changed:
            self.aligned_frame = int(self.shown_frame.max())

    def memory_bytes(self) -> int:
        return (len(self.buffer) + self.n) * (_RECORD_BYTES + 16)


class BidesAligner(Aligner):
    """BiDES: Algorithm 1 over ring buffers, lag exclusion, adaptive trigger rate."""

    name = "bides"

    def __init__(self, n: int, sc: Scenario, ctx: ServerContext) -> None:
        super().__init__(n, sc, ctx)
        self.spec = sc.bides
        self.ring = RingBuffers(n, self.spec.ring_size, OBS_WIDTH)
        self._hi = 0
        self._lo = 0
        self.rate_changes = 0
        self.filled = 0
        self.extrapolated = 0
        self.shown_count = 0

    def on_state(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None,
    ) -> None:
        self.ring.insert(node, frame, gen, obs)

    def on_states(
        self,
        t: NDArray[np.float64],
        nodes: NDArray[np.int64],
        frames: NDArray[np.int64],
        gens: NDArray[np.float64],
        obs: NDArray[np.float64],
        hlc_l: NDArray[np.float64],
        hlc_c: NDArray[np.int64],
    ) -> None:
        self.ring.insert_many(nodes, frames, gens, obs)

    def align(self, t: float) -> None:
        spec = self.spec
        res = align(
            self.ring,
            theta_lag=spec.theta_lag if spec.lag_exclusion else None,
            hole_fill=spec.hole_fill,
            prev_frame=self.aligned_frame,
        )
        self.new_snapshot = res.aligned_frame > self.aligned_frame
        self.aligned_frame = res.aligned_frame
        self.shown_frame = res.frame
        self.shown_gen = res.gen_time
        self.shown_obs = res.obs
        self.flag = res.flag
        self._note_memory()
        if spec.adaptation and self.aligned_frame >= 0:
            self._adapt(self.ctx.latest_trigger - self.aligned_frame)

    def _adapt(self, lag: int) -> None:
        spec = self.spec
        ctx = self.ctx
        if lag > spec.lag_high:
            self._hi += 1
            self._lo = 0
            if self._hi >= spec.hold_down and ctx.f_trig > spec.f_trig_min:
                ctx.set_rate(max(spec.f_trig_min, ctx.f_trig * spec.rate_down))
                self.rate_changes += 1
                self._hi = 0
        elif lag < spec.lag_low:
            self._lo += 1
            self._hi = 0
            if self._lo >= spec.hold_up and ctx.f_trig < self.sc.f_trig:
                ctx.set_rate(min(self.sc.f_trig, ctx.f_trig * spec.rate_up))
                self.rate_changes += 1
                self._lo = 0
        else:
            self._hi = 0
            self._lo = 0

    def memory_bytes(self) -> int:
        return int(self.ring.nbytes)


ALIGNERS: dict[str, type[Aligner]] = {
    "none": NoneAligner,
    "lockstep": LockstepAligner,
    "hlc": HLCAligner,
    "bides": BidesAligner,
}
