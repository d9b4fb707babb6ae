"""Where a sweep's tasks run: in this process, on local processes, or on Dask.

:func:`executor` is a context manager yielding ``submit(fn, tasks)``, an iterator of
``(task, payload)`` pairs in completion order. With Dask every task is one future
of :func:`~sigma_des.sweep.tasks.execute`; results come back through
``as_completed`` to the client, the only process that writes the results store.
On exit (also on an interrupt) unfinished futures are cancelled and a cluster
started here is shut down. ``client="processes"`` runs the tasks on a pool of local
worker processes without Dask (:mod:`sigma_des.pool`, the executor that
``compare --jobs`` and the studies use); a worker that dies takes the sweep down with
it there (Dask records it as a failed run instead).
"""

from __future__ import annotations

import logging
import signal
import threading
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from sigma_des.pool import local_pool
from sigma_des.sweep.tasks import Task, TaskFn, execute
from sigma_des.version import __version__

__all__ = ["Submit", "executor", "local_cluster", "run_inprocess", "sigint_ignored"]

#: ``submit(fn, tasks)`` → (task, payload) pairs as the tasks complete.
Submit = Callable[[TaskFn, Sequence[Task]], Iterator[tuple[Task, dict[str, Any]]]]


def run_inprocess(fn: TaskFn, tasks: Sequence[Task]) -> Iterator[tuple[Task, dict[str, Any]]]:
    """Run the tasks here, one after another (no Dask)."""
    for t in tasks:
        yield t, execute(fn, t.scenario, t.method)


@contextmanager
def executor(client: Any, n_workers: int) -> Iterator[Submit]:
    """Yield a ``submit(fn, tasks)`` that yields (task, payload) as tasks complete."""
    if client == "inprocess":
        yield run_inprocess
        return
    if client == "processes":
        with local_pool(max(1, n_workers)) as run:

            def submit_local(
                fn: TaskFn, tasks: Sequence[Task]
            ) -> Iterator[tuple[Task, dict[str, Any]]]:
                for i, payload in run(execute, [(fn, t.scenario, t.method) for t in tasks]):
                    yield tasks[i], payload

            yield submit_local
        return
    from dask.distributed import Client, as_completed

    cluster = None
    own = not isinstance(client, Client)
    if client is None or client == "local":
        cluster = local_cluster(n_workers)
        try:
            dc = Client(cluster)
        except BaseException:
            cluster.close()
            raise
    elif isinstance(client, str):
        dc = Client(client, timeout="10s")
    else:
        dc = client
    futures: list[Any] = []

    def submit(fn: TaskFn, tasks: Sequence[Task]) -> Iterator[tuple[Task, dict[str, Any]]]:
        owner = {}
        batch = []
        for i, t in enumerate(tasks):
            fut = dc.submit(execute, fn, t.scenario, t.method, pure=False, priority=len(tasks) - i)
            owner[fut.key] = t
            batch.append(fut)
        futures.extend(batch)  # cancelled on exit if still running
        for fut in as_completed(batch):
            t = owner[fut.key]
            if fut.status == "finished":
                yield t, fut.result()
            elif fut.status == "error":  # the worker died or the task did not unpickle
                exc = fut.exception()
                text = "".join(traceback.format_exception(type(exc), exc, fut.traceback()))
                yield t, {"status": "failed", "error": text, "version": __version__}
            # cancelled futures are simply not stored

    try:
        yield submit
    finally:
        if futures:
            dc.cancel(futures)
        if own:
            dc.close()
        if cluster is not None:
            cluster.close()


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while worker processes start, so they inherit the disposition.

    Ctrl-C reaches every process of the terminal's group; the workers then stay
    quiet (no ``KeyboardInterrupt`` traceback each) while the client, which still
    handles it, cancels the runs and shuts the cluster down. Python installs its
    ``KeyboardInterrupt`` handler only where SIGINT is not ignored at start-up.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def local_cluster(n_workers: int) -> Any:
    """A LocalCluster bound to 127.0.0.1 only: processes, one thread each, no dashboard."""
    from dask.distributed import LocalCluster

    with warnings.catch_warnings(), sigint_ignored():
        # the scheduler's small HTTP endpoint falls back to a free loopback port
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        return LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
