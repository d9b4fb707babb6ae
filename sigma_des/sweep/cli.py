"""The ``sigma-des sweep`` subcommand: arguments and handler.

``sigma_des.cli`` registers the subparser (with the shared scenario arguments)
through :func:`add_sweep_args` and calls :func:`run_sweep_command` with the loaded
base scenario; a :class:`~sigma_des.errors.ConfigError` raised here (a bad grid key
or value, method or seed) propagates to it and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sigma_des.config import ALL_METHODS, Scenario
from sigma_des.sweep.grid import parse_grid_args
from sigma_des.sweep.runner import Sweep

__all__ = ["add_sweep_args", "run_sweep_command"]


def add_sweep_args(sp: argparse.ArgumentParser) -> None:
    """Add the sweep options (the scenario file and ``--set`` are added by the caller)."""
    sp.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...",
        help="a grid axis (dotted key, values in TOML syntax); repeatable: the grid is "
        "the Cartesian product, e.g. --grid nodes=10,20,50 --grid net.qos=0,1",
    )
    sp.add_argument(
        "--methods",
        default=None,
        help=f"comma-separated subset of {','.join(ALL_METHODS)} (default: scenario's)",
    )
    sp.add_argument(
        "--seeds",
        default="1",
        help="N (= seeds 1..N), a..b, or a comma list like 1,2,3 (default: 1)",
    )
    sp.add_argument(
        "--store",
        default=None,
        metavar="FILE",
        help="SQLite results store (default: DIR/sweep.sqlite with --out, else sweep.sqlite)",
    )
    sp.add_argument(
        "--out", default=None, metavar="DIR", help="write runs.csv and aggregate.csv here"
    )
    where = sp.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDR",
        help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
        "(default: start a LocalCluster on 127.0.0.1)",
    )
    where.add_argument(
        "--in-process",
        action="store_true",
        help="run the tasks one by one in this process (no Dask)",
    )
    sp.add_argument(
        "--workers", type=int, default=2, help="LocalCluster worker processes (default: 2)"
    )
    sp.add_argument(
        "--retry-failed", action="store_true", help="run again the runs stored as failed"
    )
    sp.add_argument("--dry-run", action="store_true", help="validate and print the plan only")
    sp.add_argument("--force", action="store_true",
                    help="run even if the memory estimate exceeds the available memory")
    sp.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_sweep_command(args: argparse.Namespace, base: Scenario) -> int:
    """Run ``sigma-des sweep``; returns the exit status (1 if any run of the sweep failed).

    Raises:
        ConfigError: invalid grid, method or seed (before any work).
    """
    grid = parse_grid_args(args.grid)
    if args.out:  # a bad output location must not cost the whole sweep
        from sigma_des.outputs import check_out_dir

        check_out_dir(args.out)
    store = Path(args.store) if args.store else None
    if store is None:
        store = Path(args.out) / "sweep.sqlite" if args.out else Path("sweep.sqlite")
    if args.workers < 1:
        from sigma_des.errors import ConfigError

        raise ConfigError("--workers", f"must be >= 1, got {args.workers}")
    with Sweep(base, grid, args.methods, args.seeds, store) as sw:
        pending = sw.pending(args.retry_failed)
        if pending and not args.force:  # the largest run, once per worker at a time
            from sigma_des.budget import check_memory, estimate_bytes

            big = max(pending, key=lambda t: estimate_bytes(t.scenario)).scenario
            check_memory(big, 1 if args.in_process else args.workers)
        workers = 1 if args.in_process else args.workers
        print(f"sweep: {sw.describe()}")
        print(
            f"store {store}: {len(pending)} to run; "
            f"estimate ~{_dur(sw.estimate(workers, args.retry_failed))}"
            + ("" if args.scheduler else f" on {workers} worker(s)")
        )
        if args.dry_run:
            return 0
        if not args.in_process:
            from sigma_des.extras import need

            need("sweep", "dask", "distributed", instead="pass --in-process")
        client: str | None = "inprocess" if args.in_process else args.scheduler
        try:
            rep = sw.run(
                client=client,
                n_workers=args.workers,
                progress=not args.no_progress,
                retry_failed=args.retry_failed,
            )
        except KeyboardInterrupt:
            print(
                "\ninterrupted: finished runs are stored; run the same command to resume",
                file=sys.stderr,
            )
            return 130
        except OSError as e:
            print(f"sigma-des: error: cannot reach the Dask scheduler: {e}", file=sys.stderr)
            return 1
        print(rep.text())
        if args.out:
            runs, agg = sw.write(args.out)
            print(f"wrote {runs} and {agg}")
        return 1 if rep.failures else 0


def _dur(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"
