"""What every alignment method shares: the server context, the batch interface, the snapshot.

An aligner lives at the alignment server (docs/concepts/methods.md). The
engine hands it the delivered states in batches (:meth:`Aligner.on_states` with a
:class:`StateBatch`; a single state is a batch of one, :func:`one_state`; a method that
keeps nothing but ring buffers may let a compiled core store them,
:meth:`Aligner.state_ring`), tells it when a trigger is issued
(:meth:`Aligner.on_trigger`) and, at every alignment tick,
asks it to refresh the snapshot it shows (:meth:`Aligner.align`): per node the frame,
generation time, published state and a flag. Methods that steer the trigger (Lock-Step's barrier,
BiDES's adaptive rate) do so through the :class:`ServerContext` the engine passes in.
At the end it reports what it measured (:meth:`Aligner.report`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.filled import filled
from sigma_des.core.flags import MISSING
from sigma_des.events.align.hlc_clock import Released, Stamp
from sigma_des.events.align.newest import take_rows
from sigma_des.events.align.ring import RingBuffers
from sigma_des.metrics.reports import AlignerReport

__all__ = [
    "Aligner",
    "OBS_WIDTH",
    "RECORD_BYTES",
    "ServerContext",
    "StateBatch",
    "newest_rows",
    "one_state",
    "OneState",
    "take_newest",
]

#: Columns of a published state.
OBS_WIDTH = 12
#: Bytes of one buffered state record: obs + frame + generation time.
RECORD_BYTES = OBS_WIDTH * 8 + 8 + 8


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


def take_newest(
    frame: NDArray[np.int64],
    gen: NDArray[np.float64],
    obs: NDArray[np.float64],
    rows: StateBatch | Released,
) -> NDArray[np.int64]:
    """Per node, take the rows' newest state into ``frame``/``gen``/``obs`` if it is newer.

    The rule of :func:`newest_rows` (the first row of a node's highest frame, if that
    beats ``frame[node]``), applied in place: its defining loop over the rows, compiled
    (:func:`~sigma_des.events.align.newest.take_rows`).

    Returns:
        The nodes whose entry changed (ascending).
    """
    if rows.nodes.size == 1:  # a single state: the same rule without sorting
        node = int(rows.nodes[0])
        f = int(rows.frames[0])
        if f <= frame[node]:
            return rows.nodes[:0]
        frame[node] = f
        gen[node] = rows.gens[0]
        obs[node] = rows.obs[0]
        return rows.nodes
    changed = np.zeros(frame.shape[0], dtype=np.bool_)
    take_rows(frame, gen, obs, rows.nodes, rows.frames, rows.gens, rows.obs, changed)
    return np.flatnonzero(changed)


class StateBatch(NamedTuple):
    """Delivered states, row ``j`` the ``j``-th arrival: what :meth:`Aligner.on_states` takes.

    Attributes:
        t: ``(m,)`` arrival times (non-decreasing).
        nodes: ``(m,)`` senders.
        frames: ``(m,)`` the states' frames.
        gens: ``(m,)`` their generation times.
        obs: ``(m, OBS_WIDTH)`` the published states.
        hlc_l: ``(m,)`` HLC stamps' logical parts (meaningful for HLC only).
        hlc_c: ``(m,)`` HLC stamps' counters (meaningful for HLC only).
    """

    t: NDArray[np.float64]
    nodes: NDArray[np.int64]
    frames: NDArray[np.int64]
    gens: NDArray[np.float64]
    obs: NDArray[np.float64]
    hlc_l: NDArray[np.float64]
    hlc_c: NDArray[np.int64]


def one_state(
    t: float,
    node: int,
    frame: int,
    gen: float,
    obs: NDArray[np.float64],
    stamp: Stamp | None = None,
) -> StateBatch:
    """A single delivered state as a batch of one (the per-message engines' path).

    Args:
        t: arrival time.
        node: sender.
        frame: the state's frame.
        gen: its generation time.
        obs: ``(OBS_WIDTH,)`` the published state.
        stamp: its HLC stamp (HLC only; None: ``l = NaN, c = 0``).

    Returns:
        The batch of one, for :meth:`Aligner.on_states`.
    """
    return OneState(int(np.size(obs))).fill(t, node, frame, gen, obs, stamp)


class OneState:
    """A reusable batch of one, for engines that hand states over one by one.

    :meth:`fill` overwrites the same seven length-1 arrays and returns them as a
    :class:`StateBatch`, equal to :func:`one_state` of the same arguments, without
    allocating. Safe because an aligner copies what it keeps of a batch (every one
    in this package does: rows go into its own arrays) and never holds the batch.
    """

    def __init__(self, width: int = OBS_WIDTH) -> None:
        f = np.zeros(3)
        i = np.zeros(3, dtype=np.int64)
        self.batch = StateBatch(f[0:1], i[0:1], i[1:2], f[1:2], np.zeros((1, width)), f[2:3],
                                i[2:3])

    def fill(
        self,
        t: float,
        node: int,
        frame: int,
        gen: float,
        obs: NDArray[np.float64],
        stamp: Stamp | None = None,
    ) -> StateBatch:
        """The batch holding this one state (see :func:`one_state` for the arguments)."""
        b = self.batch
        b.t[0] = t
        b.nodes[0] = node
        b.frames[0] = frame
        b.gens[0] = gen
        b.obs[0] = obs
        if stamp is None:
            b.hlc_l[0], b.hlc_c[0] = math.nan, 0
        else:
            b.hlc_l[0], b.hlc_c[0] = stamp.l, stamp.c
        return b


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
    """Base class: the shown snapshot, no-op hooks and the memory peak.

    Args:
        n: number of nodes.
        ctx: the engine's side of the server.

    Attributes:
        shown_frame: frame of the state shown per node (-1: none).
        shown_gen: generation time of the shown state (NaN: none).
        shown_obs: ``(n, 12)`` shown published states.
        flag: per node EXACT/FILLED/EXTRAPOLATED/MISSING.
        aligned_frame: the snapshot's reference frame (-1 before any).
        new_snapshot: set by :meth:`align` when the snapshot advanced.
        peak_bytes: most bytes buffered at an alignment tick so far.
    """

    name = "base"

    def __init__(self, n: int, ctx: ServerContext) -> None:
        self.n = n
        self.ctx = ctx
        self.shown_frame = filled(n, -1, np.int64)
        self.shown_gen = filled(n, np.nan)
        self.shown_obs = filled((n, OBS_WIDTH), np.nan)
        self.flag = filled(n, MISSING, np.uint8)
        self.aligned_frame = -1
        self.new_snapshot = False
        self.peak_bytes = 0

    def on_trigger(self, frame: int, t: float) -> None:
        """A trigger for ``frame`` was issued at ``t``."""

    def on_states(self, batch: StateBatch) -> None:
        """States arrived: ``batch`` row ``j`` is ``batch.nodes[j]``'s state of ``batch.frames[j]``.

        Rows are in arrival order (``batch.t`` non-decreasing); ``hlc_l``/``hlc_c`` are
        meaningful for HLC only.
        """
        raise NotImplementedError

    def align(self, t: float) -> None:
        """Refresh the shown snapshot (alignment tick)."""
        raise NotImplementedError

    def state_ring(self) -> RingBuffers | None:
        """The ring buffers that hold everything this method keeps of a delivered state.

        An aligner whose :meth:`on_states` is exactly :meth:`RingBuffers.insert` of the
        batch returns its buffers, and a compiled message core may then store each state
        it delivers there itself (:func:`~sigma_des.events.align.ring.insert_row`, the
        same rule, in arrival order) instead of handing batches over; this base, and
        every method that keeps more than that, returns None.
        """
        return None

    def memory_bytes(self) -> int:
        """Bytes of state buffered by the alignment server now."""
        return self.n * RECORD_BYTES

    def note_memory(self) -> None:
        """Fold the current buffer size into :attr:`peak_bytes` (once per alignment tick)."""
        self.peak_bytes = max(self.peak_bytes, self.memory_bytes())

    def report(self) -> AlignerReport:
        """What this method measured over the run."""
        return AlignerReport(peak_bytes=self.peak_bytes)
