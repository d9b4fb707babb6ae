"""How the compiled core's event table grows (docs/concepts/engines.md).

Every queued message holds an event slot. When a method saturates the broker
(``none`` and ``hlc`` at N = 1 000) the broker's backlog is model state that grows for
the whole run: ≈ 10^6 slots after 60 simulated seconds. Growing such a table by
allocating a larger one and copying held the old and the new table at once, twice
the table at the moment of each growth, which set the run's peak memory
(docs/concepts/engines.md, "The event table's memory"). Here each array of ``cap`` (or
``arena``) rows keeps its contents in one of three ways:

* **in place** (:data:`IN_PLACE`: the event slots, the free list, the run arena):
  every row may hold live data, so the array is reallocated where it lies
  (``ndarray.resize``; for a large array the C library moves its pages with
  ``mremap`` instead of copying them), and nothing is held twice;
* **live prefix** (:data:`PREFIX`: the heap of run heads, the pending buffer, the
  run table): only the first rows, as many as the queue scalar named, hold data; a
  new zeroed array (:func:`fresh`: its pages untouched until used) receives them;
* **scratch** (:data:`SCRATCH`): filled and read within one call, a new zeroed array.

The payload pool (:data:`POOL`: the rows of the payloads that slots carry, and their
free list) has rows of its own, fewer than the slots (a trigger carries none), and
grows in place when fewer than needed are free.

As nothing is copied whole, the table can grow in smaller steps
(:func:`grown_capacity`: by an eighth), so less of it lies unused.

The core hands out no views of these arrays (Python reads them between calls of the
compiled loop only), which is what makes the in-place reallocation safe.
"""

from __future__ import annotations

import ctypes
import gc
import mmap
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.support import CohortFallback

__all__ = ["GROWTH", "IN_PLACE", "POOL", "PREFIX", "SCRATCH", "TABLE", "fresh", "grow",
           "before_run", "grown_capacity", "run_finished", "trim_heap", "trims_batched"]

#: The table grows by at least ``1 / GROWTH`` of its slots (a growth copies nothing
#: whole, so small steps cost little and leave less unused room).
GROWTH = 8
#: Arrays reallocated where they lie (every row may be live).
IN_PLACE = ("ev_int", "ev_float", "free", "run_t", "run_k")
#: Arrays whose first ``S[Q_INT][scalar]`` rows are live: their only contents.
PREFIX = {"heap_t": CO.QI_HEAP, "heap_k": CO.QI_HEAP, "heap_r": CO.QI_HEAP,
          "pend_t": CO.QI_PN, "pend_k": CO.QI_PN, "run_pos": CO.QI_NRUN, "run_end": CO.QI_NRUN}
#: Scratch arrays of the queue's sealing and compaction (no contents between calls).
SCRATCH = ("run_fwd", "bounds")
#: The payload pool and its free list (``pool`` rows), reallocated where they lie.
POOL = ("pool", "pool_free")
#: Every array of the event table (``cap``, ``arena`` or ``pool`` rows).
TABLE = (*IN_PLACE, *PREFIX, *SCRATCH, *POOL)


#: Arrays from this many bytes on get their own mapping (:func:`fresh`).
FRESH_MIN = 1 << 20


def fresh(shape: tuple[int, ...], dtype: Any) -> NDArray[Any]:
    """A zeroed array whose pages cost no memory until they are written.

    ``np.zeros`` of a few MB may get reused heap memory from the C library, which
    ``calloc`` then writes zeros over: measured at N = 1 000, the heap of run heads and
    the pending buffer (a few thousand rows in use) were resident in whole, 46 MB at 10^6
    slots. A large array here is its own anonymous mapping (zero pages, unmapped when
    the array goes).
    """
    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    if nbytes < FRESH_MIN:
        return np.zeros(shape, dtype=dtype)
    return np.frombuffer(mmap.mmap(-1, nbytes), dtype=dtype).reshape(shape)


@lru_cache(maxsize=1)
def _malloc_trim() -> Any:
    """glibc's ``malloc_trim``, or None where the C library has none."""
    try:
        return getattr(ctypes.CDLL(None), "malloc_trim", None)
    except OSError:  # pragma: no cover - no C library to load
        return None


def trim_heap() -> bool:
    """Hand the free memory of the C library's heap back to the system, before a run.

    The arrays a run frees (its event table, its results' samples) are memory the C
    library keeps for reuse: glibc raises its mmap threshold as large blocks are freed
    (up to 32 MB), so later blocks of that size come from the heap, and freed heap
    pages stay resident (< 1 ms). Returns whether it trimmed (False where there is no
    ``malloc_trim``).
    """
    fn = _malloc_trim()
    if fn is None:
        return False
    fn(0)
    return True


#: Node-seconds (nodes x simulated seconds) from which a finished run's cyclic garbage
#: is collected before the next run: a full collection costs ~0.1 s with numba loaded,
#: < 1 % of such a run (N = 1 000: >= 10 s simulated), too much for the short runs of a
#: sweep, and for the env's scenes (each declares a long run but is dropped unfinished:
#: collecting before every one made a reset of 100 scenes cost 8 s instead of 0.1 s).
COLLECT_FROM = 10_000.0
_owed = [False]  # a finished large run left garbage: the next run collects it


def run_finished(node_seconds: float) -> None:
    """A run of ``node_seconds`` (nodes x simulated seconds) is over: if it was large
    (:data:`COLLECT_FROM`), the next :func:`before_run` collects its cyclic garbage."""
    if node_seconds >= COLLECT_FROM:
        _owed[0] = True


def before_run(trim: bool = True) -> None:
    """Give the memory the runs before this one left back to the system (a ``compare
    --jobs`` worker runs several); ``trim=False``: no heap trim (a run refilling a retired
    run's arrays, which the retired run freed nothing large of: a trim, ~30 µs, would
    hand back nothing worth it and the episode's allocations would take it again).

    A finished run is cyclic garbage (its kernel's queue, handlers and engine refer to
    each other), with its physics ring (47 MB at N = 1 000) and draw tables: freed at
    the next full collection only, as the engine pauses the collector during a run.
    Measured in a worker at N = 1 000, 60 s, the second run started with 60-70 MB of
    such garbage and 20-30 MB of freed heap pages resident (:func:`trim_heap`).

    A full collection runs only when a large run finished since the last one
    (:func:`run_finished`); the heap is trimmed before every run.
    """
    if _owed[0]:
        _owed[0] = False
        gc.collect()
    if trim:
        if _batched[0]:
            _batched[1] = True  # the batch's end trims
        else:
            trim_heap()
    _fix_mmap_threshold()


_batched = [0, False]  # open trims_batched blocks, a trim owed at their end


@contextmanager
def trims_batched() -> Iterator[None]:
    """The runs set up inside share one heap trim (:func:`before_run`), at the block's end:
    a learning env starting many small scenes at once trims once, not once a scene."""
    _batched[0] += 1
    try:
        yield
    finally:
        _batched[0] -= 1
        if _batched[0] == 0 and _batched[1]:
            _batched[1] = False
            trim_heap()


@lru_cache(maxsize=1)
def _fix_mmap_threshold() -> bool:
    """Blocks of :data:`FRESH_MIN` or more from their own mappings, always (glibc's
    ``mallopt(M_MMAP_THRESHOLD)``; by default glibc raises the threshold up to 32 MB as
    large blocks are freed, and a table growing through the heap is copied, leaving
    resident holes)."""
    try:
        fn = getattr(ctypes.CDLL(None), "mallopt", None)
    except OSError:  # pragma: no cover - no C library to load
        return False
    return fn is not None and fn(-3, FRESH_MIN) == 1  # M_MMAP_THRESHOLD


def grown_capacity(old: int, need: int) -> int:
    """The event table's slots after growing from ``old`` slots, ``need`` more at least
    (an eighth more if that is more; no more than a queue key can address).

    Raises:
        CohortFallback: ``need`` more slots are more than a queue key can address
            (:data:`~sigma_des.events.fast.codes.MAX_SLOTS`).
    """
    if old + need > CO.MAX_SLOTS:
        raise CohortFallback(f"more than {CO.MAX_SLOTS} messages in flight")
    return min(old + max(old // GROWTH, need), CO.MAX_SLOTS)


def _free_on_top(free: NDArray[Any], iv: NDArray[Any], top: int, old: int, new: int) -> None:
    """Rows ``old .. new - 1`` onto free list ``free`` (its top ``iv[top]``), the lowest
    on top: rows are taken lowest first, so the unused ones are never touched."""
    nfree = int(iv[top])
    free[nfree : nfree + new - old] = np.arange(new - 1, old - 1, -1, dtype=free.dtype)
    iv[top] = nfree + new - old


def grow(S: tuple[NDArray[Any], ...], need: int) -> tuple[NDArray[Any], ...]:
    """The state ``S`` with ``need`` free event slots and ``need`` free payload rows at
    least (each grown if fewer are free).

    The queue's order, every slot's contents and every payload are kept; the new slots
    and rows join their free lists on top, so they are taken first (lowest first).

    Returns:
        The state: the in-place arrays are the same objects, the others new ones.
    """
    iv = S[L.INTS]
    if iv[CO.I_PFREE] < need:
        _grow_pool(S, need)
    if iv[CO.I_FREE] < need:
        S = _grow_slots(S, need)
    return S


def _grow_pool(S: tuple[NDArray[Any], ...], need: int) -> None:
    """Grow the payload pool and its free list in place (their contents kept)."""
    pool, free = S[L.POOL], S[L.POOL_FREE]
    old = pool.shape[0]
    new = grown_capacity(old, need)
    pool.resize((new, pool.shape[1]), refcheck=False)  # no views exist (module docstring)
    free.resize((new,), refcheck=False)
    _free_on_top(free, S[L.INTS], CO.I_PFREE, old, new)


def _grow_slots(S: tuple[NDArray[Any], ...], need: int) -> tuple[NDArray[Any], ...]:
    """Grow the event slots and the queue's arrays (module docstring)."""
    old = S[L.EV_INT].shape[0]
    new = grown_capacity(old, need)
    qi = S[L.Q_INT]
    made: dict[str, NDArray[Any]] = {}
    for f in L.FIELDS:
        if not f.shape or f.shape[0] not in ("cap", "arena"):
            continue
        a = S[L.INDEX[f.name]]
        shape = (a.shape[0] * new // old, *a.shape[1:])  # arena: the same ratio, >= new
        if f.name in IN_PLACE:
            a.resize(shape, refcheck=False)  # no views exist (module docstring)
            continue
        b = fresh(shape, a.dtype)
        if f.name in PREFIX:
            m = int(qi[PREFIX[f.name]])
            b[:m] = a[:m]
        elif f.name not in SCRATCH:
            raise AssertionError(f"state field {f.name!r}: no growth rule")
        made[f.name] = b
    _free_on_top(S[L.FREE], S[L.INTS], CO.I_FREE, old, new)
    return L.replaced(S, made)
