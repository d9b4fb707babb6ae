"""The ``bides`` method: Algorithm 1 over ring buffers, lag exclusion, adaptive trigger rate.

docs/concepts/methods.md: the server keeps each node's last ``ring_size``
states (:class:`~sigma_des.events.align.ring.RingBuffers`), builds the snapshot with
Algorithm 1 (:func:`~sigma_des.events.align.ring.align`: hole filling, lag
exclusion) and adapts the trigger rate to the alignment lag (latest trigger minus
aligned frame) with hold-down/hold-up counters. Time warp (rollbacks at the nodes)
is the engine's part.
"""

from __future__ import annotations

from sigma_des.events.align.base import OBS_WIDTH, Aligner, ServerContext, StateBatch
from sigma_des.events.align.ring import RingBuffers, align
from sigma_des.events.align.spec import AlignParams, BidesSpec

__all__ = ["BidesAligner"]


class BidesAligner(Aligner):
    """BiDES: Algorithm 1 over ring buffers, lag exclusion, adaptive trigger rate.

    Args:
        n: number of nodes.
        spec: BiDES's parts and parameters.
        ctx: the engine's side of the server.
        f_trig: nominal trigger rate (Hz): adaptation never raises the rate above it.
    """

    name = "bides"

    def __init__(self, n: int, spec: BidesSpec, ctx: ServerContext, f_trig: float) -> None:
        super().__init__(n, ctx)
        self.spec = spec
        self.f_nominal = f_trig
        self.ring = RingBuffers(n, spec.ring_size, OBS_WIDTH)
        self._hi = 0
        self._lo = 0
        self.rate_changes = 0

    @classmethod
    def build(cls, n: int, ctx: ServerContext, params: AlignParams) -> BidesAligner:
        """The registry's constructor: ``params.bides`` and the nominal ``f_trig``."""
        return cls(n, params.bides, ctx, params.f_trig)

    def on_states(self, batch: StateBatch) -> None:
        """Store the states in the ring buffers."""
        self.ring.insert(batch.nodes, batch.frames, batch.gens, batch.obs)

    def state_ring(self) -> RingBuffers:
        """The ring buffers: :meth:`on_states` stores the states there and nothing else."""
        return self.ring

    def align(self, t: float) -> None:
        """Algorithm 1, then one step of the rate adaptation."""
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
        self.note_memory()
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
            if self._lo >= spec.hold_up and ctx.f_trig < self.f_nominal:
                ctx.set_rate(min(self.f_nominal, ctx.f_trig * spec.rate_up))
                self.rate_changes += 1
                self._lo = 0
        else:
            self._hi = 0
            self._lo = 0

    def memory_bytes(self) -> int:
        """The ring buffers' arrays."""
        return int(self.ring.nbytes)
