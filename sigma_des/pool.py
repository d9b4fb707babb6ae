"""The local executor: many independent calls on this machine, one way.

:func:`local_pool` is what ``compare --jobs`` (:func:`sigma_des.api.compare`), the
lab's paper studies and engine benchmark's
per-case children run on; the Dask executor of :mod:`sigma_des.sweep.executors`
is its distributed counterpart for sweeps. Three ways to run:

* ``jobs == 1`` (and not ``fresh``): in this process, one call after another;
* ``jobs > 1``: a pool of up to ``jobs`` worker processes;
* ``fresh=True``: every call in a new worker process (``max_tasks_per_child=1``),
  so peak RSS and caches are per call (the benchmark measures them).

Results come back as ``(index, result)`` pairs in completion order;
:func:`run_all` returns them in the order of the calls. An exception raised by a
call is re-raised in the caller.

Workers never outlive the caller: on Linux each asks the kernel for SIGKILL when its
parent dies (``PR_SET_PDEATHSIG``, so even a SIGKILLed ``sigma-des`` takes them
along); under ``forkserver`` and off Linux a thread in each worker watches the
caller. They ignore SIGINT: the terminal's Ctrl-C reaches the whole process group,
and the caller decides; when an exception (Ctrl-C included) leaves the pool's block,
the calls not started are cancelled and the workers still running are terminated at
once (nothing half-done is waited for).
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any

__all__ = ["Submit", "die_with_parent", "local_pool", "run_all"]

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


_PR_SET_PDEATHSIG = 1


def _pdeathsig() -> bool:
    """Ask Linux for SIGKILL when our parent dies; True if granted."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return bool(libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0)
    except (OSError, AttributeError):
        return False


def _watch(caller: int) -> None:
    """Block until ``caller`` ends, then SIGKILL this process."""
    try:
        fd = os.pidfd_open(caller)  # readable once the process has ended (Linux >= 5.3)
    except (OSError, AttributeError):
        while True:
            try:
                os.kill(caller, 0)
            except ProcessLookupError:
                break
            except PermissionError:
                pass
            time.sleep(0.5)
    else:
        select.select([fd], [], [])
    os.kill(os.getpid(), signal.SIGKILL)


def die_with_parent(caller: int, direct: bool = True) -> None:
    """Worker initializer: die (SIGKILL) when the caller dies; ignore SIGINT.

    Args:
        caller: the pid of the process that made the pool.
        direct: ``caller`` is this worker's parent (``fork``, ``spawn``): Linux's
            ``PR_SET_PDEATHSIG`` does the job, and a worker whose caller is already
            gone exits at once. Otherwise (``forkserver``: the server is the parent,
            and it lives as long as its children do) and off Linux, a thread watches
            the caller.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    armed = direct and _pdeathsig()
    if direct and os.getppid() != caller:  # died before the request took effect
        os._exit(1)
    if not armed:
        threading.Thread(target=_watch, args=(caller,), daemon=True).start()


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started and terminate the workers now."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(OSError, ValueError):
            p.terminate()
    for p in procs:
        with contextlib.suppress(OSError, ValueError, AssertionError):
            p.join(5.0)
    pool.shutdown(wait=True)


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
    pool = ProcessPoolExecutor(
        max_workers=jobs, mp_context=ctx, max_tasks_per_child=1 if fresh else None,
        initializer=die_with_parent,
        initargs=(os.getpid(), ctx.get_start_method() != "forkserver"),
    )

    def submit(
        fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]
    ) -> Iterator[tuple[int, Any]]:
        futures = {pool.submit(fn, *args): i for i, args in enumerate(calls)}
        return _completed(futures)

    try:
        yield submit
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)


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
