"""The local executor: many independent calls on this machine, one way.

:func:`local_pool` is what ``compare --jobs`` (:func:`sigma_des.api.compare`), the
paper studies (:func:`sigma_des.studies.run_study`) and the engine benchmark's
per-case children run on; the Dask executor of :mod:`sigma_des.sweep.executors`
is its distributed counterpart for sweeps. Three ways to run:

* ``jobs == 1`` (and not ``fresh``): in this process, one call after another;
* ``jobs > 1``: a pool of up to ``jobs`` worker processes;
* ``fresh=True``: every call in a new worker process (``max_tasks_per_child=1``),
  so peak RSS and caches are per call (the benchmark measures them).

Results come back as ``(index, result)`` pairs in completion order;
:func:`run_all` returns them in the order of the calls. An exception raised by a
call is re-raised in the caller.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any

__all__ = ["Submit", "local_pool", "run_all"]

#: ``submit(fn, calls)``: submits ``fn(*args)`` for every ``args`` of ``calls`` at
#: once and returns an iterator of ``(index, result)`` in completion order.
Submit = Callable[[Callable[..., Any], Sequence[tuple[Any, ...]]], Iterator[tuple[int, Any]]]


def _inprocess(
    fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]
) -> Iterator[tuple[int, Any]]:
    for i, args in enumerate(calls):
        yield i, fn(*args)


def _completed(futures: dict[Future[Any], int]) -> Iterator[tuple[int, Any]]:
    for fut in as_completed(futures):
        yield futures[fut], fut.result()


@contextmanager
def local_pool(
    jobs: int,
    start_method: str | None = None,
    fresh: bool = False,
    preload: Sequence[str] = (),
) -> Iterator[Submit]:
    """Yield a :data:`Submit` running calls here, in a process pool, or one process each.

    Args:
        jobs: the most calls running at once (1 and not ``fresh``: in this process).
        start_method: the ``multiprocessing`` start method of the workers
            (``spawn``, ``forkserver``, ``fork``; None: the platform's default, or
            ``forkserver`` when ``fresh``).
        fresh: run every call in a new worker process (not with ``fork``).
        preload: modules a ``forkserver`` imports once before forking the workers.

    Raises:
        ValueError: ``jobs`` < 1, or ``fresh`` with the ``fork`` start method.
    """
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if fresh and start_method is None:
        start_method = "forkserver"
    if jobs == 1 and not fresh:
        yield _inprocess
        return
    ctx = mp.get_context(start_method)
    if preload and ctx.get_start_method() == "forkserver":
        ctx.set_forkserver_preload(list(preload))
    with ProcessPoolExecutor(
        max_workers=jobs, mp_context=ctx, max_tasks_per_child=1 if fresh else None
    ) as pool:

        def submit(
            fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]
        ) -> Iterator[tuple[int, Any]]:
            futures = {pool.submit(fn, *args): i for i, args in enumerate(calls)}
            return _completed(futures)

        yield submit


def run_all(
    fn: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    jobs: int = 1,
    start_method: str | None = None,
    fresh: bool = False,
    preload: Sequence[str] = (),
) -> list[Any]:
    """``[fn(*args) for args in calls]`` on :func:`local_pool` (at most ``len(calls)`` workers)."""
    workers = max(1, min(jobs, len(calls)))
    out: list[Any] = [None] * len(calls)
    with local_pool(workers, start_method, fresh, preload) as submit:
        for i, result in submit(fn, calls):
            out[i] = result
    return out
