"""BiDES swarm state alignment (the paper's Algorithm 1) over per-node ring buffers.

The server keeps the last ``k`` states of every node in :class:`RingBuffers` (slot
``frame % k``); :func:`align` builds a snapshot at one frame, vectorised over nodes.

Decisions where the model (docs/concepts/methods.md) leaves room (tested):

* **Considered nodes** are those with any state; with ``theta_lag`` set, a node
  whose newest frame lags the swarm's newest by more than ``theta_lag`` frames is
  left out of the minimum (optimistic alignment) and shown EXTRAPOLATED.
* **Aligned frame** ``F = max(prev_frame, min latest over considered)``: never back.
* A considered node with a state at exactly ``F`` shows it (EXACT).
* A hole at ``F`` (lost packet, or a node behind ``F`` because ``prev_frame``
  held ``F`` up):

  - ``hole_fill=True``: linear interpolation of ``obs`` between the nearest
    buffered frames below and above ``F`` (``gen_time`` of the lower one,
    ``frame`` reported as ``F``); if only one side exists, that state is shown
    as is (its own ``frame`` and ``gen_time``). Flag FILLED either way.
  - ``hole_fill=False``: the nearest older buffered state is shown as is (its own
    ``frame``, which differs from ``F``), flagged FILLED (zero-order hold); if
    there is no older state the node is MISSING (newer states are not shown).

* An excluded (lagging) node is EXTRAPOLATED: ``obs`` linearly extrapolated
  from its two newest buffered frames to ``F`` (a copy of the newest if it has
  only one) and reported at ``frame`` ``F`` (the model: the slot stands for the
  aligned frame), ``gen_time`` that of its newest state (so its AoI stays honest).
* A shown ``frame`` differs from ``F`` only for a hole shown as a single buffered
  neighbour: the only non-zero frame spread. MISSING rows: ``frame = -1``, NaN times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from sigma_des.core.filled import filled
from sigma_des.core.flags import EXACT, EXTRAPOLATED, FILLED, MISSING

__all__ = ["AlignResult", "RingBuffers", "align", "align_in", "insert_row"]

_BIG = np.iinfo(np.int64).max


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def insert_row(frame: np.ndarray, gen_time: np.ndarray, obs: np.ndarray, latest: np.ndarray,
               node: int, f: int, gen: float, src: np.ndarray, r: int) -> bool:
    """The rule of :meth:`RingBuffers.insert` for one row: ``node``'s state of frame ``f``
    (``f >= 0``), generated at ``gen``, its observation the first ``width`` columns of
    ``src[r]``; whether it was stored.

    The one place of the rule: :func:`_insert_rows` applies it row by row, and the
    compiled message core applies it to each state it delivers to a ring it was handed
    (:meth:`~sigma_des.events.align.base.Aligner.state_ring`). Compiled without numba's
    reference counting (it allocates nothing), as the core's kernels are.
    """
    slot = f % frame.shape[1]
    if frame[node, slot] >= f:
        return False
    frame[node, slot] = f
    gen_time[node, slot] = gen
    for c in range(obs.shape[2]):
        obs[node, slot, c] = src[r, c]
    if f > latest[node]:
        latest[node] = f
    return True


@njit(cache=True)
def _insert_rows(frame: np.ndarray, gen_time: np.ndarray, obs: np.ndarray, latest: np.ndarray,
                 nodes: np.ndarray, frames: np.ndarray, gens: np.ndarray, rows: np.ndarray,
                 accepted: np.ndarray) -> None:
    """The rule of :meth:`RingBuffers.insert`, row after row in order (compiled)."""
    for j in range(nodes.shape[0]):
        accepted[j] = insert_row(frame, gen_time, obs, latest, nodes[j], frames[j], gens[j],
                                 rows, j)


def _as_rows(x: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """``x`` broadcast to ``shape`` as contiguous float64 (a column view of that shape and
    dtype, as the compiled core's delivery batches are, is copied without broadcasting)."""
    if isinstance(x, np.ndarray) and x.shape == shape and x.dtype == np.float64:
        return np.ascontiguousarray(x)
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), shape))


class RingBuffers:
    """The last ``k`` states of each of ``n`` nodes.

    Args:
        n: number of nodes.
        k: ring length (frames kept per node).
        width: number of observation columns.

    Attributes:
        frame: ``(n, k)`` frame held by each slot (-1 = empty).
        gen_time: ``(n, k)`` generation time of each slot's state (NaN if empty).
        obs: ``(n, k, width)`` the states.
        latest: ``(n,)`` newest frame ever inserted per node (-1 = none).
    """

    def __init__(self, n: int, k: int, width: int) -> None:
        if n < 0 or k < 1 or width < 0:
            raise ValueError(f"need n >= 0, k >= 1, width >= 0; got {n}, {k}, {width}")
        self.n, self.k, self.width = int(n), int(k), int(width)
        self.frame: NDArray[np.int64] = filled((n, k), -1, np.int64)
        self.gen_time: NDArray[np.float64] = filled((n, k), np.nan)
        self.obs: NDArray[np.float64] = np.zeros((n, k, width))
        self.latest: NDArray[np.int64] = filled(n, -1, np.int64)

    def insert(
        self,
        nodes: ArrayLike,
        frames: ArrayLike,
        gen_times: ArrayLike,
        obs: ArrayLike,
    ) -> NDArray[np.bool_]:
        """Store each row's state of ``frames[j]`` in its node's slot ``frames[j] % k``.

        A batch (e.g. one cohort of arrivals) or a single state (scalars: a batch of
        one), compiled. Rows are taken in order; a row is stored unless its slot
        already holds this frame (a duplicate) or a newer one. The buffers end up the
        same for any order of the rows: per ``(node, slot)`` the newest frame wins,
        and of identical ``(node, frame)`` rows the first.

        Returns:
            ``(m,)`` per row, whether it was stored.

        Raises:
            ValueError: a frame is negative.
        """
        fr1 = np.asarray(frames)
        if fr1.size == 1:  # a single state (the per-message engines): no compiled call
            return np.array([self._insert_one(int(np.asarray(nodes).item()), int(fr1.item()),
                                              float(np.asarray(gen_times).item()), obs)])
        nd = np.ascontiguousarray(nodes, dtype=np.int64).ravel()
        fr = np.ascontiguousarray(fr1, dtype=np.int64).ravel()
        gt = _as_rows(gen_times, nd.shape)
        ob = _as_rows(obs, (nd.size, self.width))
        if fr.size and fr.min() < 0:
            raise ValueError("frames must be >= 0")
        accepted = np.zeros(nd.size, dtype=np.bool_)
        _insert_rows(self.frame, self.gen_time, self.obs, self.latest, nd, fr, gt, ob, accepted)
        return accepted

    def _insert_one(self, node: int, frame: int, gen_time: float, obs: ArrayLike) -> bool:
        """The rule of :meth:`insert` for one row, in Python (cheaper than a compiled call)."""
        if frame < 0:
            raise ValueError("frames must be >= 0")
        slot = frame % self.k
        if self.frame[node, slot] >= frame:
            return False
        self.frame[node, slot] = frame
        self.gen_time[node, slot] = gen_time
        self.obs[node, slot] = np.reshape(obs, self.width)
        if frame > self.latest[node]:
            self.latest[node] = frame
        return True

    @property
    def nbytes(self) -> int:
        """Bytes held by the buffers' arrays."""
        return int(self.frame.nbytes + self.gen_time.nbytes + self.obs.nbytes + self.latest.nbytes)


#: the rows :func:`align` starts from, ``(frame -1, gen NaN, obs NaN, flag MISSING)`` by
#: ``(n, width)``: copied (one call each) instead of filled afresh at every tick
_BLANK: dict[tuple[int, int], tuple[NDArray[np.int64], NDArray[np.float64],
                                    NDArray[np.float64], NDArray[np.uint8]]] = {}


@dataclass
class AlignResult:
    """A swarm snapshot produced by :func:`align`.

    Attributes:
        aligned_frame: the frame ``F`` the snapshot stands for (-1 before any).
        frame: ``(n,)`` frame of the state shown per node (-1 = missing).
        gen_time: ``(n,)`` generation time of the state shown (NaN = missing).
        obs: ``(n, width)`` the states shown (NaN rows = missing).
        flag: ``(n,)`` uint8, one of EXACT, FILLED, EXTRAPOLATED, MISSING.
    """

    aligned_frame: int
    frame: NDArray[np.int64]
    gen_time: NDArray[np.float64]
    obs: NDArray[np.float64]
    flag: NDArray[np.uint8]


def align(
    buf: RingBuffers,
    *,
    theta_lag: int | None,
    hole_fill: bool,
    prev_frame: int = -1,
) -> AlignResult:
    """Align the swarm (Algorithm 1); see the module docstring for the rules.

    Args:
        buf: the per-node ring buffers.
        theta_lag: lag (frames behind the newest node) beyond which a node is
            excluded and extrapolated; None = never exclude.
        hole_fill: fill holes by interpolation (True) or hold the older state.
        prev_frame: the previous aligned frame (F never decreases).

    Returns:
        The snapshot.
    """
    if theta_lag is not None and theta_lag < 0:
        raise ValueError(f"theta_lag must be >= 0 or None, got {theta_lag}")
    n = buf.latest.shape[0]
    # the rows are allocated here: a compiled call that returned fresh arrays would box
    # them through Python code at every tick (numba's _numba_unpickle), where a Ctrl-C
    # can land and come out as a SystemError
    blank = _BLANK.get((n, buf.obs.shape[2]))
    if blank is None:
        blank = _BLANK[(n, buf.obs.shape[2])] = (
            np.full(n, -1, dtype=np.int64), np.full(n, np.nan),
            np.full((n, buf.obs.shape[2]), np.nan), np.full(n, MISSING, dtype=np.uint8))
    # fresh rows (the snapshot keeps them)
    frame, gen, obs, flag = blank[0].copy(), blank[1].copy(), blank[2].copy(), blank[3].copy()
    F = _align_all(  # noqa: N806 - paper's name
        buf.frame, buf.gen_time, buf.obs, buf.latest, -1 if theta_lag is None else theta_lag,
        hole_fill, int(prev_frame), frame, gen, obs, flag)
    return AlignResult(aligned_frame=int(F), frame=frame, gen_time=gen, obs=obs, flag=flag)


@njit(cache=True)
def _align_all(fr: np.ndarray, gt: np.ndarray, ob: np.ndarray, latest: np.ndarray,
               theta_lag: int, hole_fill: bool, prev_frame: int, frame: np.ndarray,
               gen: np.ndarray, obs: np.ndarray, flag: np.ndarray) -> int:
    """:func:`align` in one compiled call (``theta_lag`` -1: never exclude): the considered
    nodes, ``F = max(prev_frame, min latest over them)`` and the rows (:func:`_align_rows`)
    written into ``frame``, ``gen``, ``obs``, ``flag`` (which come in as -1, NaN, NaN,
    MISSING); every row left so and ``F = prev_frame`` while no node has a state."""
    n = latest.shape[0]
    return align_in(fr, gt, ob, latest, theta_lag, hole_fill, prev_frame, frame, gen, obs,
                    flag, np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_))


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def align_in(fr: np.ndarray, gt: np.ndarray, ob: np.ndarray, latest: np.ndarray,
             theta_lag: int, hole_fill: bool, prev_frame: int, frame: np.ndarray,
             gen: np.ndarray, obs: np.ndarray, flag: np.ndarray, has: np.ndarray,
             considered: np.ndarray) -> int:
    """:func:`_align_all` with its two per-node scratch rows given (``(n,)`` bool each,
    any contents): nothing is allocated, so a loop compiled without reference counting
    (the compiled control loop, :mod:`sigma_des.events.fast.control`) may call it."""
    n = latest.shape[0]
    newest = -1
    for i in range(n):
        newest = max(newest, latest[i])
    if newest < 0:
        return prev_frame
    for i in range(n):
        has[i] = latest[i] >= 0
        considered[i] = False
    low = _BIG
    for i in range(n):
        # plain branches: ``considered[i] = has[i] and ...`` in this loop, next to the
        # minimum, marked a node out in numba 0.68.1, where Python kept it
        # (tests/events/align/test_ring.py, the per-node reference)
        li = latest[i]
        if li < 0 or (theta_lag >= 0 and newest - li > theta_lag):
            continue
        considered[i] = True
        if li < low:
            low = li
    F = max(prev_frame, low)  # noqa: N806 - paper's name
    _align_rows(fr, gt, ob, has, considered, F, hole_fill, frame, gen, obs, flag)
    return F


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _align_rows(fr: np.ndarray, gt: np.ndarray, ob: np.ndarray, has: np.ndarray,
                considered: np.ndarray, F: int, hole_fill: bool, frame: np.ndarray,  # noqa: N803
                gen: np.ndarray, obs: np.ndarray, flag: np.ndarray) -> None:
    """Per node: the exact, filled, held or extrapolated row at ``F`` (module docstring).

    A node holding frame ``F`` holds it in slot ``F % k`` (:meth:`RingBuffers.insert`
    puts frame ``f`` nowhere else), read first. Ties go to the first slot, as
    ``argmax``/``argmin`` do; weights are
    ``float(a) / float(b)`` of integer frame differences, then ``o + w * (p - o)``
    per column — the arithmetic of the rules, row by row.
    """
    n, k = fr.shape
    width = ob.shape[2]
    for i in range(n):
        if not has[i]:
            continue
        if not considered[i]:  # lagging: extrapolate from its two newest frames
            s_new = 0
            for s in range(1, k):
                if fr[i, s] > fr[i, s_new]:
                    s_new = s
            f1 = fr[i, s_new]
            s_old = -1
            for s in range(k):
                if s != s_new and (s_old < 0 or fr[i, s] > fr[i, s_old]):
                    s_old = s
            f_old = fr[i, s_old] if s_old >= 0 else -1
            two = f_old >= 0
            f0 = f_old if two else f1 - 1
            w = (F - f1) / (f1 - f0)
            for c in range(width):
                o_new = ob[i, s_new, c]
                o_old = ob[i, s_old, c] if two else o_new
                obs[i, c] = o_new + w * (o_new - o_old)
            gen[i] = gt[i, s_new]
            frame[i] = F
            flag[i] = EXTRAPOLATED
            continue
        s_exact = F % k  # the one slot that can hold frame F (a frame f goes to f % k)
        if F >= 0 and fr[i, s_exact] == F:  # the common case: no scan of the ring
            _show_slot(fr, gt, ob, i, s_exact, frame, gen, obs)
            flag[i] = EXACT
            continue
        s_exact = -1
        s_lo = -1
        s_hi = -1
        for s in range(k):
            f = fr[i, s]
            if f == F and s_exact < 0:
                s_exact = s
            if 0 <= f < F and (s_lo < 0 or f > fr[i, s_lo]):
                s_lo = s
            if f > F and (s_hi < 0 or f < fr[i, s_hi]):
                s_hi = s
        sel = -1
        if s_exact >= 0:
            sel = s_exact
            flag[i] = EXACT
        elif s_lo >= 0 and s_hi >= 0 and hole_fill:
            lo = fr[i, s_lo]
            hi = fr[i, s_hi]
            w = (F - lo) / (hi - lo)
            for c in range(width):
                o_lo = ob[i, s_lo, c]
                obs[i, c] = o_lo + w * (ob[i, s_hi, c] - o_lo)
            gen[i] = gt[i, s_lo]
            frame[i] = F
            flag[i] = FILLED
        elif s_lo >= 0:
            sel = s_lo
            flag[i] = FILLED
        elif s_hi >= 0 and hole_fill:
            sel = s_hi
            flag[i] = FILLED
        if sel >= 0:
            _show_slot(fr, gt, ob, i, sel, frame, gen, obs)


@njit(cache=True, inline="always", _nrt=False)  # type: ignore[call-overload]
def _show_slot(fr: np.ndarray, gt: np.ndarray, ob: np.ndarray, i: int, s: int,
               frame: np.ndarray, gen: np.ndarray, obs: np.ndarray) -> None:
    """Node ``i`` shows the state of its slot ``s`` as it is (frame, gen time, obs)."""
    frame[i] = fr[i, s]
    gen[i] = gt[i, s]
    for c in range(ob.shape[2]):
        obs[i, c] = ob[i, s, c]
