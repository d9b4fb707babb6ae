"""The ``sigma-des warmup`` subcommand: compile the numba kernels into the cache, in parallel.

``sigma_des.cli`` adds its arguments with :func:`add_args` and dispatches to :func:`run`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from sigma_des.errors import ConfigError

__all__ = ["add_args", "run"]


def add_args(w: argparse.ArgumentParser) -> None:
    """Add the arguments of ``sigma-des warmup`` to its subparser ``w``."""
    w.add_argument("--jobs", type=int, default=os.cpu_count() or 1, metavar="N",
                   help="compile up to N groups of kernels at once (default: the CPU count)")


def run(args: argparse.Namespace) -> int:
    """Run the warm-up and print what each unit cost; exit status 2 on a bad ``--jobs``."""
    from sigma_des.warmup.units import warm

    if args.jobs < 1:
        print(f"sigma-des: error: {ConfigError('--jobs', f'must be >= 1, got {args.jobs}')}",
              file=sys.stderr)
        return 2
    t = time.perf_counter()
    for u in warm(args.jobs):
        print(f"{u.unit:8s} {u.wall_s:7.2f} s wall  {u.cpu_s:7.2f} s CPU  "
              f"{u.compiled} kernels compiled")
    print(f"warm-up done in {time.perf_counter() - t:.2f} s wall ({args.jobs} jobs)")
    return 0
