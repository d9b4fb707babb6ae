"""Parameter sweeps: a grid over scenario keys × methods × seeds, on Dask, resumable.

* :class:`Sweep` — plan, run (Dask ``LocalCluster``, a remote scheduler, or in-process),
  read back and aggregate a sweep; every finished run is stored at once.
* :class:`ResultStore` — the SQLite (WAL) store, one record per
  (config hash, seed, method).
* :func:`run_task` — the default task (one method on one scenario).
* :func:`aggregate_rows` — mean, std, n and 95 % CI half-width over seeds.
* :func:`parse_grid_args`, :func:`parse_seeds` — the ``--grid``/``--seeds`` syntax.

See ``docs/howto/sweep-dask.md``.
"""

from sigma_des.sweep.aggregate import aggregate_rows, t975, write_csv
from sigma_des.sweep.grid import (
    apply_point,
    expand_grid,
    parse_grid_args,
    parse_methods,
    parse_seeds,
    validate_points,
)
from sigma_des.sweep.runner import RunReport, Sweep
from sigma_des.sweep.store import ResultStore
from sigma_des.sweep.tasks import Task, estimate_seconds, execute, run_task

__all__ = [
    "ResultStore",
    "RunReport",
    "Sweep",
    "Task",
    "aggregate_rows",
    "apply_point",
    "estimate_seconds",
    "execute",
    "expand_grid",
    "parse_grid_args",
    "parse_methods",
    "parse_seeds",
    "run_task",
    "t975",
    "validate_points",
    "write_csv",
]
