"""Where the compiled core's deliveries go: the aligner, a recording tap, the collector.

A state reaching the server (:func:`~sigma_des.events.fast.server.at_server`) goes

* **straight into the aligner's ring buffers** when the aligner keeps nothing else of a
  state (:meth:`~sigma_des.events.align.base.Aligner.state_ring`: BiDES). The loop
  applies :meth:`~sigma_des.events.align.ring.RingBuffers.insert`'s rule
  (:func:`~sigma_des.events.align.ring.insert_row`) to each state in arrival order, on
  the aligner's own arrays, so the ring at an alignment tick is the one the batches
  handed over before made (the insert's result does not depend on how the rows are
  batched, and the aligner reads its ring only at a tick, after the core ran to it);
* **into a buffer for Python** otherwise (the aligner's ``on_states`` in arrival
  order), and also when a recording tap takes the states (:meth:`Deliveries.states`
  hands the buffer to both).

Latencies (trigger, state, command) are buffered in the order the loop measures them
and appended to the collector's series when a buffer fills and at the run's end
(:meth:`Deliveries.latencies`): the collector reads them only when the run is over, so
when they are appended changes nothing of its results.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.align.base import OBS_WIDTH, Aligner, StateBatch
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.tap import Tap
from sigma_des.metrics.collector import Collector

__all__ = ["LAT_FRAMES", "Deliveries", "records_states"]

#: Capacity of each latency buffer in deliveries per node (and the server): the
#: collector's series grow once per this many frames' triggers, not once per frame.
LAT_FRAMES = 16

State = tuple[NDArray[Any], ...]


class _Host(Protocol):
    """What the deliveries read of the engine (at each hand-over: a tap may be attached
    after the core was built)."""

    aligner: Aligner
    collector: Collector
    tap: Tap


def records_states(tap: Tap) -> bool:
    """Whether ``tap`` takes state deliveries (overrides :meth:`Tap.states`)."""
    return getattr(type(tap), "states", Tap.states) is not Tap.states


class Deliveries:
    """The hand-over of one run's deliveries (see the module docstring).

    Args:
        host: the engine (its aligner, collector and recording tap).
        n: number of nodes.
    """

    def __init__(self, host: _Host, n: int) -> None:
        self.host = host
        self.n = n
        #: the aligner's ring the loop stores states in, or None (``on_states``)
        self.ring = host.aligner.state_ring()

    def dims(self) -> dict[str, int]:
        """The latency buffers' capacity and the ring's dimensions (1 x 1 without one)."""
        ring = self.ring
        return {"lat": LAT_FRAMES * (self.n + 1), "ring_n": ring.n if ring else 1,
                "ring_k": ring.k if ring else 1}

    def given(self) -> dict[str, NDArray[Any]]:
        """The ring's arrays, shared in place (placeholders without a ring)."""
        ring = self.ring
        if ring is None:
            return {"ring_frame": np.full((1, 1), -1, dtype=np.int64),
                    "ring_gen": np.full((1, 1), np.nan),
                    "ring_obs": np.zeros((1, 1, OBS_WIDTH)),
                    "ring_latest": np.full(1, -1, dtype=np.int64)}
        return {"ring_frame": ring.frame, "ring_gen": ring.gen_time, "ring_obs": ring.obs,
                "ring_latest": ring.latest}

    def params(self, q: NDArray[np.int64]) -> None:
        """Set ``Q_RING`` and ``Q_OUT`` (before any tap is attached: see :meth:`watch`)."""
        q[CO.Q_RING] = int(self.ring is not None)
        q[CO.Q_OUT] = int(self.ring is None)

    def watch(self, S: State) -> None:
        """Buffer states for Python if the aligner or the run's tap takes them."""
        S[L.IPARAMS][CO.Q_OUT] = int(self.ring is None or records_states(self.host.tap))

    def states(self, S: State) -> None:
        """Hand the buffered state deliveries to the aligner (without a ring) and the tap."""
        iv = S[L.INTS]
        o = int(iv[CO.I_OUT])
        if not o:
            return
        h = self.host
        oi = S[L.OUT_INT][:o]
        of = S[L.OUT_FLOAT][:o]
        obs = of[:, 3 : 3 + OBS_WIDTH]
        if self.ring is None:
            h.aligner.on_states(
                StateBatch(of[:, 0], oi[:, 0], oi[:, 1], of[:, 1], obs, of[:, 2], oi[:, 2])
            )
        h.tap.states(of[:, 0], oi[:, 0], oi[:, 1], of[:, 1], obs)
        iv[CO.I_OUT] = 0

    def latencies(self, S: State) -> None:
        """Append the buffered latencies to the collector's series, in order."""
        iv = S[L.INTS]
        for k in range(3):
            m = int(iv[CO.I_LAT + k])
            if m:
                self.host.collector.delivered_batch(k + 1, S[L.LAT_BUF][k, :m].copy(), 0)
                iv[CO.I_LAT + k] = 0
