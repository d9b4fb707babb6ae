"""The ``rpc`` method: AirSim-style synchronous per-vehicle calls every frame.

AirSim's vehicles are reached by msgpack-rpc over TCP; a client's ``call`` blocks
until its response. Here the server plays the frame loop of such a simulator
(parameters in :class:`~sigma_des.events.align.spec.RpcSpec`):

1. frame k starts when its trigger is issued: the server sends a request (a
   trigger message to that one vehicle) to the first ``in_flight`` vehicles
   (0 = all at once, one outstanding call per vehicle);
2. a vehicle steps to frame k (its compute job) and responds with its state;
3. the server's game thread handles each response (``call_time``, FIFO) and then
   sends the next vehicle its request, if any is left;
4. once all N responses are handled the game thread renders the frame
   (``render_time`` + ``render_per_vehicle`` × N): rendering and the calls share
   that thread, so render load delays the next frame's physics;
5. the rendered frame is the shown snapshot, and trigger k+1 is issued then, not
   sooner than ``1/f_trig`` after trigger k (the engine's barrier rule).

A vehicle that never responds (crashed) stalls the loop, as a blocking call would.
"""

from __future__ import annotations

from typing import Protocol, cast

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.flags import EXACT, MISSING
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError
from sigma_des.events.align.base import (
    OBS_WIDTH,
    RECORD_BYTES,
    Aligner,
    ServerContext,
    StateBatch,
)
from sigma_des.events.align.spec import AlignParams, RpcSpec
from sigma_des.net.links import dist_cache

__all__ = ["RpcAligner", "RpcContext"]

_CALL, _RENDER = 0, 1


class RpcContext(ServerContext, Protocol):
    """A server context that can send one vehicle its request."""

    def rpc_call(self, node: int, frame: int) -> None:
        """Send ``node`` the request for ``frame`` (a trigger to that node only)."""
        ...


class RpcAligner(Aligner):
    """Synchronous calls to every vehicle, then one render, per frame.

    Args:
        n: number of vehicles.
        spec: the frame loop's parameters.
        ctx: the engine's side of the server (an :class:`RpcContext`).
        seed: the run's root seed (call and render times are drawn from it).
        middleware: ``net.middleware``; must be ``"mqtt"``.

    Raises:
        ConfigError: ``middleware`` is not ``"mqtt"`` (key ``methods``).
    """

    name = "rpc"

    def __init__(
        self, n: int, spec: RpcSpec, ctx: ServerContext, seed: int, middleware: str
    ) -> None:
        if middleware != "mqtt":
            raise ConfigError(
                "methods",
                "rpc models msgpack-rpc over TCP and needs net.middleware = 'mqtt' (with "
                f"zero broker service it is a plain relay), got {middleware!r}",
            )
        super().__init__(n, ctx)
        self.rctx = cast(RpcContext, ctx)
        streams = RandomStreams(seed)
        self._call_t = dist_cache(n + 1, spec.call_time, streams, "rpc.call")
        self._render_t = dist_cache(n + 1, spec.render_time, streams, "rpc.render")
        self._per_frame = spec.render_per_vehicle * n
        self._limit = spec.in_flight if spec.in_flight > 0 else n
        self.busy = 0.0  # the game thread: busy until
        self.current = -1
        self._next = 0
        self._handled = 0
        self._got = np.zeros(n, dtype=np.bool_)
        self._gen = np.full(n, np.nan)
        self._obs = np.full((n, OBS_WIDTH), np.nan)
        self._dirty = False
        self._done_frame = -1
        self._done_gen = np.full(n, np.nan)
        self._done_obs = np.full((n, OBS_WIDTH), np.nan)
        self.calls = 0

    @classmethod
    def build(cls, n: int, ctx: ServerContext, params: AlignParams) -> RpcAligner:
        """The registry's constructor: ``params.rpc``, the seed and the middleware."""
        return cls(n, params.rpc, ctx, params.seed, params.middleware)

    def on_trigger(self, frame: int, t: float) -> None:
        """Start frame ``frame``: send the first ``in_flight`` requests."""
        self.current = frame
        self._got[:] = False
        self._next = 0
        self._handled = 0
        for _ in range(min(self._limit, self.n)):
            self._call_next(frame)

    def _call_next(self, frame: int) -> None:
        node = self._next
        self._next += 1
        self.calls += 1
        self.rctx.rpc_call(node, frame)

    def on_states(self, batch: StateBatch) -> None:
        """Queue each response of the current frame on the game thread, in order."""
        t, nodes, frames, gens = batch.t, batch.nodes, batch.frames, batch.gens
        for j in range(nodes.size):
            self._one(float(t[j]), int(nodes[j]), int(frames[j]), float(gens[j]), batch.obs[j])

    def _one(self, t: float, node: int, frame: int, gen: float, obs: NDArray[np.float64]) -> None:
        if frame != self.current or self._got[node]:
            return
        self._got[node] = True
        self._gen[node] = gen
        self._obs[node] = obs
        start = t if t > self.busy else self.busy
        self.busy = start + self._call_t.get(_CALL, node, frame, 0)
        self.ctx.call_at(self.busy, self._on_handled, frame)

    def _on_handled(self, frame: int) -> None:
        self._handled += 1
        if self._next < self.n:
            self._call_next(frame)
        if self._handled < self.n:
            return
        now = self.ctx.now()
        start = now if now > self.busy else self.busy
        self.busy = start + self._render_t.get(_RENDER, self.n, frame, 0) + self._per_frame
        self.ctx.call_at(self.busy, self._on_rendered, frame)

    def _on_rendered(self, frame: int) -> None:
        self._done_frame = frame
        self._done_gen[:] = self._gen
        self._done_obs[:] = self._obs
        self._dirty = True
        self.ctx.barrier_done(frame)

    def align(self, t: float) -> None:
        """Show the last rendered frame."""
        self.new_snapshot = self._dirty
        if self._dirty:
            # the rendered frame's states (the next frame's are still arriving)
            self.shown_frame[:] = self._done_frame
            self.shown_gen[:] = self._done_gen
            self.shown_obs[:] = self._done_obs
            self.flag[:] = np.where(np.isnan(self._done_gen), MISSING, EXACT)
            self.aligned_frame = self._done_frame
            self._dirty = False
        self.note_memory()

    def memory_bytes(self) -> int:
        """The frame being collected and the rendered one."""
        return 2 * self.n * RECORD_BYTES
