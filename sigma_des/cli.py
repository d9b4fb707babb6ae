"""The ``sigma-des`` command line.

Each subcommand's module is imported only when that subcommand runs (or shows its
``--help``): the table :data:`COMMANDS` holds the one-line help of every command and
where its arguments are defined, so ``sigma-des --help``, ``--version`` and
``config`` start without numba, SciPy or the engines.

Bad input (unknown key, wrong type, out-of-range value, a missing optional package)
exits with status 2 and one line naming the key and what is allowed.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from sigma_des.errors import ConfigError
from sigma_des.version import __version__

__all__ = ["COMMANDS", "main"]

#: The lock file ``compare`` holds in its ``--out`` folder while it runs.
LOCK_NAME = ".sigma-des.lock"


class Command(NamedTuple):
    """One subcommand: its help line, where its arguments are added, what it needs."""

    help: str
    #: adds the command's own arguments to its subparser (``module:function``: imported
    #: only when the command is chosen)
    args: str | Callable[[argparse.ArgumentParser], None]
    #: True if the command takes a scenario (file or shipped name) and ``--set``.
    scenario: bool = False
    #: the extra (pyproject.toml) the command needs, named when one of its packages is missing
    extra: str = ""


_EPILOG = """\
A scenario is a TOML file or the name of a shipped one (e.g. latency_tolerance);
--set KEY=VALUE overrides any key. 'sigma-des COMMAND --help' lists a command's
options. Bad input exits with status 2 and a message naming the key."""


def _function(ref: str | Callable[..., Any]) -> Callable[..., Any]:
    if callable(ref):
        return ref
    module, name = ref.split(":")
    return getattr(importlib.import_module(module), name)  # type: ignore[no-any-return]


def _scenario_args(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("scenario", nargs="?",
                    help="scenario TOML file or shipped scenario name (default: built-in)")
    sp.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key (dotted, value in TOML syntax); "
        "repeatable, e.g. --set nodes=50 --set net.host_link.loss.p=0.1",
    )


def _no_args(sp: argparse.ArgumentParser) -> None:
    """``config`` has only the scenario's arguments."""


def _compare_args(c: argparse.ArgumentParser) -> None:
    from sigma_des.config import ALL_METHODS

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


COMMANDS: dict[str, Command] = {
    "compare": Command("run alignment methods side by side on one scenario; print a table, "
                       "write results.csv and summary.json", _compare_args, True),
    "config": Command("print the full resolved scenario as TOML (start from the defaults)",
                      _no_args, True),
    "sweep": Command("a grid of scenario keys x methods x seeds on Dask, resumable "
                     "(docs/howto/sweep-dask.md)", "sigma_des.sweep.cli:add_sweep_args", True,
                     "experiments"),
    "replay": Command("rebuild recorded trajectories (compare --record) at any rate",
                      "sigma_des.replay.cli:add_replay_args", extra="record"),
    "layout": Command("write a Foxglove layout for a recording: 3-D panel following the "
                      "swarm, AoI plot (docs/howto/record-foxglove.md)",
                      "sigma_des.record.layout:add_layout_args", extra="record"),
    "live": Command("run the scenario live over a real Mosquitto broker (docs/howto/live.md)",
                    "sigma_des.live.cli:add_live_args", True, "live"),
    "calibrate": Command("fit DES parameters from one or more live runs; writes a scenario "
                         "TOML",
                         "sigma_des.calibrate.cli:add_calibrate_args", extra="live"),
    "predict": Command("predict a target from a calibration, every method, with intervals "
                       "(docs/howto/predict.md)",
                       "sigma_des.calibrate.predict_cli:add_predict_args", extra="live"),
    "capacity": Command("the largest N each method holds within missed-frame and latency "
                        "budgets, from a calibration",
                        "sigma_des.calibrate.predict_cli:add_capacity_args", extra="live"),
    "tune": Command("fit the aircraft model to a flight log (GA + DTW); writes fitted.toml",
                    "sigma_des.tuning.cli:add_args", extra="tuning"),
    "flightlog": Command("write a tuning flight log flown by a JSBSim glider (minisgs)",
                         "sigma_des.tuning.glider_cli:add_args", extra="physics"),
    "warmup": Command("compile the numba kernels once, after installing (in parallel)",
                      "sigma_des.warmup.cli:add_args"),
}

def _selected(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv`` (the first word that is not an option)."""
    return next((a for a in argv if not a.startswith("-")), None)


def _parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The parser; only the command selected in ``argv`` gets (and imports) its arguments."""
    p = argparse.ArgumentParser(
        prog="sigma-des", epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Discrete-event simulation of time alignment (none, Lock-Step, HLC, "
        "BiDES) in distributed UAV-swarm simulators.")
    p.add_argument("--version", action="version", version=f"sigma-des {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = _selected(argv)
    for name, cmd in COMMANDS.items():
        sp = sub.add_parser(name, help=cmd.help, description=cmd.help[0].upper() + cmd.help[1:]
                            + ".")
        if name == chosen:
            if cmd.scenario:
                _scenario_args(sp)
            _function(cmd.args)(sp)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    try:
        return _main(argv)
    except KeyboardInterrupt:  # e.g. Ctrl-C while the libraries load: no traceback
        print("sigma-des: interrupted", file=sys.stderr)
        return 130
    finally:  # an --out folder made for a run that wrote nothing into it goes again
        outputs = sys.modules.get("sigma_des.outputs")  # not loaded: nothing was made
        if outputs is not None:
            outputs.remove_unused()


def _main(argv: Sequence[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser(argv).parse_args(argv)
    try:
        return _run(args)
    except ModuleNotFoundError as e:
        from sigma_des.extras import missing_extra

        err = missing_extra(e, args.command, COMMANDS[args.command].extra)
        if err is None:
            raise
        print(f"sigma-des: error: {err}", file=sys.stderr)
        return 2
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command; ConfigError and missing packages propagate to :func:`main`."""
    command = args.command
    if command == "replay":
        from sigma_des.extras import need

        need("replay", "mcap", "orjson")
        return _function("sigma_des.replay.cli:run_replay")(args)  # type: ignore[no-any-return]
    if command == "layout":
        return _function("sigma_des.record.layout:run_layout")(args)  # type: ignore[no-any-return]
    if command == "tune":
        return _function("sigma_des.tuning.cli:run")(args)  # type: ignore[no-any-return]
    if command == "flightlog":
        return _function("sigma_des.tuning.glider_cli:run")(args)  # type: ignore[no-any-return]
    if command == "warmup":
        return _function("sigma_des.warmup.cli:run")(args)  # type: ignore[no-any-return]
    if command in ("predict", "capacity"):
        return _function(f"sigma_des.calibrate.predict_cli:run_{command}")(args)  # type: ignore[no-any-return]
    if command == "calibrate":
        return _function("sigma_des.calibrate.cli:run_calibrate")(args)  # type: ignore[no-any-return]
    from sigma_des.config import load

    sc = load(args.scenario, args.sets)
    if sc.dynamics.startswith("jsbsim:") and command != "config":
        from sigma_des.extras import need

        need(f"dynamics={sc.dynamics}", "jsbsim")
    if command == "config":
        return _config(sc)
    _say_if_compiling()
    if command == "live":
        return _function("sigma_des.live.cli:run_live_command")(args, sc)  # type: ignore[no-any-return]
    if command == "sweep":
        return _function("sigma_des.sweep.cli:run_sweep_command")(args, sc)  # type: ignore[no-any-return]
    return _compare(args, sc)


def _say_if_compiling() -> None:
    """One line before a run that will compile the kernels first (a silent minute otherwise)."""
    from sigma_des.jitcache import kernels_cached

    if not kernels_cached():
        print("sigma-des: compiling kernels once (~1 min; `sigma-des warmup` does it ahead)",
              file=sys.stderr, flush=True)


def _config(sc: Any) -> int:
    """Print the scenario as TOML; automatic values are written as such, to stay automatic."""
    from sigma_des.config import NODES_PER_HOST, WARMUP_FRACTION, to_toml

    sys.stdout.write(
        f"# hosts = 0 means ceil(nodes / {NODES_PER_HOST}) hosts (here {sc.hosts}); "
        f"warmup = -1 means {WARMUP_FRACTION:g} x duration (here {sc.warmup:g} s)\n"
        + to_toml(sc)
    )
    return 0


def _compare(args: argparse.Namespace, sc: Any) -> int:
    from sigma_des.config import ALL_METHODS
    from sigma_des.outputs import check_out_dir

    methods = None
    if args.methods is not None:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for m in methods:
            if m not in ALL_METHODS:
                raise ConfigError(
                    "--methods", f"unknown method {m!r}; allowed: {', '.join(ALL_METHODS)}"
                )
    if args.out:  # a bad output location must not cost the whole run
        if not args.no_plots:
            from sigma_des.extras import need

            need("--out", "matplotlib", instead="pass --no-plots")
        check_out_dir(args.out)
    lock = None
    if args.out:  # a second run into the same folder is refused while this one runs
        from pathlib import Path

        from sigma_des.lock import OutputLock

        lock = OutputLock(Path(args.out) / LOCK_NAME, "--out", args.out)
    try:
        return _compare_run(args, sc, methods)
    finally:
        if lock is not None:
            lock.release()


def _compare_run(args: argparse.Namespace, sc: Any, methods: list[str] | None) -> int:
    """``compare`` once its options are checked (and its ``--out`` locked)."""
    if args.record is not None:
        from sigma_des.extras import need

        need("--record", "mcap", "orjson")
        from sigma_des.record.cli import check_record_path

        check_record_path(args.record)
    from sigma_des.api import compare

    res = compare(
        sc, methods, progress=not args.no_progress, jobs=args.jobs, force=args.force,
        record=args.record,
    )
    from sigma_des.live.interrupts import Interrupts

    with Interrupts() as sig:
        sig.mask()  # the results are in hand: a Ctrl-C now is noted, never cuts the writes
        print(res.table())
        for note in res.warnings():
            print(f"sigma-des: warning: {note}", file=sys.stderr)
        if res.interrupted:
            print(f"sigma-des: interrupted; kept the {len(res.methods)} finished method(s): "
                  f"{', '.join(res.methods)}", file=sys.stderr)
        if args.out:
            csv_path, json_path = res.write(args.out)
            print(f"wrote {csv_path}, {csv_path.parent / 'wall.csv'} and {json_path}")
            if not args.no_plots:  # matplotlib was checked before the run
                from sigma_des.plots import write_plots

                paths = write_plots(res, args.out)
                print(f"plots: {', '.join(p.name for p in paths)}")
    return 130 if res.interrupted else 0


if __name__ == "__main__":
    raise SystemExit(main())
