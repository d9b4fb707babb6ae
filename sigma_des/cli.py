"""The ``sigma-des`` command line.

Commands:
  compare  run alignment methods side by side on one scenario, print a table,
           write results.csv (tidy) and summary.json.
  config   print the full resolved scenario as TOML (start from the defaults).
  sweep    run a grid of scenario keys x methods x seeds on Dask (a LocalCluster
           by default), resumable through a SQLite results store; writes
           runs.csv and aggregate.csv (see docs/SWEEPS.md).
  live     run the scenario live over a real Mosquitto broker (docs/LIVE.md).
  calibrate  fit DES parameters from a live run; writes a scenario TOML.
  replay   rebuild the trajectories of a recording (compare --record) at any
           rate with a chosen interpolant; writes a tidy CSV.
  warmup   compile the numba kernels into numba's cache (once, after installing;
           the kernel groups in parallel processes).
  tune     fit the quadrotor / fixed-wing model to a CSV flight log (GA + DTW;
           see sigma_des/tuning); writes a fitted.toml for dynamics_params.

Bad input (unknown key, wrong type, out-of-range value) exits with status 2 and
a message naming the key and what is allowed.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from sigma_des import __version__
from sigma_des.config import ALL_METHODS, NODES_PER_HOST, load, to_toml
from sigma_des.errors import ConfigError
from sigma_des.outputs import check_out_dir

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="sigma-des", description=__doc__.split("\n\n")[0])
    p.add_argument("--version", action="version", version=f"sigma-des {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    def scenario_args(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("scenario", nargs="?", help="scenario TOML file (default: built-in)")
        sp.add_argument(
            "--set",
            dest="sets",
            action="append",
            default=[],
            metavar="KEY=VALUE",
            help="override a scenario key (dotted, value in TOML syntax); "
            "repeatable, e.g. --set nodes=50 --set net.host_link.loss.p=0.1",
        )

    c = sub.add_parser("compare", help="run alignment methods side by side")
    scenario_args(c)
    c.add_argument(
        "--methods",
        default=None,
        help=f"comma-separated subset of {','.join(ALL_METHODS)} (default: scenario's)",
    )
    c.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="write results.csv, wall.csv, summary.json and plots here",
    )
    c.add_argument("--no-progress", action="store_true", help="no progress bar")
    c.add_argument("--no-plots", action="store_true",
                   help="with --out: do not draw the PNG plots next to the tables")
    c.add_argument("--force", action="store_true",
                   help="run even if the memory estimate exceeds the available memory")
    c.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="run up to N methods at once in worker processes (default 1; "
                   "results are identical)")
    c.add_argument("--record", default=None, metavar="FILE.mcap",
                   help="also record every run to this MCAP file (settings: record.*)")

    g = sub.add_parser("config", help="print the resolved scenario as TOML")
    scenario_args(g)

    from sigma_des.sweep.cli import add_sweep_args

    s = sub.add_parser("sweep", help="grid x methods x seeds on Dask, resumable")
    scenario_args(s)
    add_sweep_args(s)
    from sigma_des.replay.cli import add_replay_parser

    add_replay_parser(sub)

    from sigma_des.live.cli import add_calibrate_parser, add_live_parser

    add_live_parser(sub, scenario_args)
    add_calibrate_parser(sub)

    from sigma_des.tuning.cli import add_parser as add_tune_parser

    add_tune_parser(sub)

    from sigma_des.cache.cli import add_parser as add_warmup_parser

    add_warmup_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    args = _parser().parse_args(argv)
    if args.command == "replay":
        from sigma_des.replay.cli import run_replay

        return run_replay(args)
    if args.command == "tune":
        from sigma_des.tuning.cli import run as run_tune

        return run_tune(args)
    if args.command == "warmup":
        from sigma_des.cache.cli import run as run_warmup

        return run_warmup(args)
    try:
        if args.command == "calibrate":
            from sigma_des.live.cli import run_calibrate

            return run_calibrate(args)
        sc = load(args.scenario, args.sets)
        if args.command == "live":
            from sigma_des.live.cli import run_live_command

            return run_live_command(args, sc)
        if args.command == "config":
            sys.stdout.write(
                f"# hosts = 0 (the default) means ceil(nodes / {NODES_PER_HOST}) hosts "
                f"({NODES_PER_HOST} nodes each); here that is hosts = {sc.hosts}\n"
                + to_toml(sc)
            )
            return 0
        if args.command == "sweep":
            from sigma_des.sweep.cli import run_sweep_command

            return run_sweep_command(args, sc)
        from sigma_des.api import compare

        methods = None
        if args.methods is not None:
            methods = [m.strip() for m in args.methods.split(",") if m.strip()]
            for m in methods:
                if m not in ALL_METHODS:
                    raise ConfigError(
                        "--methods", f"unknown method {m!r}; allowed: {', '.join(ALL_METHODS)}"
                    )
        if args.out:  # a bad output location must not cost the whole run
            check_out_dir(args.out)
        if args.record is not None:
            from sigma_des.record.cli import check_record_path

            check_record_path(args.record)
        res = compare(
            sc, methods, progress=not args.no_progress, jobs=args.jobs, force=args.force,
            record=args.record,
        )
        print(res.table())
        if args.out:
            csv_path, json_path = res.write(args.out)
            print(f"wrote {csv_path}, {csv_path.parent / 'wall.csv'} and {json_path}")
            if not args.no_plots:
                _plots(res, args.out)
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    return 0


def _plots(res: object, out: str) -> None:
    """Draw the comparison's plots into ``out`` (a one-line note without matplotlib)."""
    from sigma_des.plots import MISSING_NOTE, have_matplotlib, write_plots

    if not have_matplotlib():
        print(MISSING_NOTE)
        return
    paths = write_plots(res, out)  # type: ignore[arg-type]
    print(f"plots: {', '.join(p.name for p in paths)}")


if __name__ == "__main__":
    raise SystemExit(main())
