"""The ``sigma-des live`` subcommand.

``live`` runs the scenario over a real Mosquitto broker (ours, started on a free
loopback port, unless ``--broker``), prints ``compare``'s table and with ``--out``
writes ``results.csv``, ``summary.json`` (``"mode": "live"``) and
``messages.csv.gz`` (one row per message: kind, host, node, frame, t_send,
t_recv, …) and ``cpu.csv`` (each process's CPU over the idle and metrics windows).
``sigma-des calibrate`` (:mod:`sigma_des.calibrate.cli`) fits the DES to such a
directory.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from sigma_des.config import METHODS, Scenario
from sigma_des.errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from sigma_des.api import Results

__all__ = ["PASSWORD_ENV", "add_live_args", "password", "run_live_command"]

#: Environment variable holding the MQTT password (when neither option gives one).
PASSWORD_ENV = "SIGMA_DES_MQTT_PASSWORD"


def add_live_args(p: argparse.ArgumentParser) -> None:
    """Add the arguments of ``live`` to its subparser ``p`` (the caller adds the scenario's)."""
    p.add_argument("--methods", default=None,
                   help=f"comma-separated subset of {','.join(METHODS)} (default: scenario's)")
    p.add_argument("--broker", default=None, metavar="HOST:PORT",
                   help="use a running broker (default: start our own Mosquitto on 127.0.0.1)")
    p.add_argument("--username", default="", help="MQTT user for --broker")
    p.add_argument("--password", default=None,
                   help=f"MQTT password for --broker (visible to other users in the process "
                   f"list: prefer --password-file or ${PASSWORD_ENV})")
    p.add_argument("--password-file", default=None, metavar="FILE",
                   help="read the MQTT password from the first line of FILE")
    p.add_argument("--tls-ca", default=None, metavar="FILE",
                   help="connect to --broker over TLS, its certificate checked against the CA "
                   "certificate(s) in FILE (PEM)")
    p.add_argument("--broker-port", type=int, default=None, metavar="PORT",
                   help="port of our own broker (default: a free one)")
    p.add_argument("--max-inflight", type=int, default=0, metavar="N",
                   help="QoS 1 in-flight window per client (default 0: unlimited)")
    p.add_argument("--bundle", action="store_true",
                   help="a host sends the states its nodes finish together as one PUBLISH")
    p.add_argument("--no-impair", action="store_true",
                   help="do not apply the scenario's link latency/loss in the clients")
    p.add_argument("--no-step-delay", action="store_true",
                   help="nodes publish right after their real step (no drawn step_time)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write results.csv, summary.json, messages.csv.gz and cpu.csv here")
    p.add_argument("--no-plots", action="store_true", help="with --out: no PNG plots")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--force", action="store_true",
                   help="run even if there are too many host processes for the CPU cores or "
                   "the memory estimate exceeds the available memory")
    p.add_argument("--record", default=None, metavar="FILE.mcap",
                   help="record every message to an MCAP file (sigma_des.record; "
                   "settings: record.*)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run each physics host on a worker of this Dask scheduler (clocks "
                   "reconciled over the broker; docs/howto/live.md)")
    p.add_argument("--placement", default="spread", metavar="spread|pack|FILE",
                   help="with --scheduler: hosts round-robin over the workers (spread), all "
                   "on one (pack), or a TOML host -> worker map (default: spread)")


def run_live_command(args: argparse.Namespace, sc: Scenario) -> int:
    """Run ``live``; ConfigError propagates to the caller (exit 2)."""
    from sigma_des.extras import need

    need("live", "paho", "pandas", extra="live")
    from sigma_des.live.broker import parse_broker
    from sigma_des.live.interrupts import Interrupts
    from sigma_des.live.runner import LiveOptions, run_live

    methods = None
    if args.methods is not None:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for m in methods:
            if m not in METHODS:
                allowed = ", ".join(METHODS)
                raise ConfigError("--methods", f"unknown method {m!r}; allowed: {allowed}")
    if args.broker is not None:
        parse_broker(args.broker)
    if args.broker_port is not None and not 1 <= args.broker_port <= 65535:
        raise ConfigError("--broker-port", f"must be in 1..65535, got {args.broker_port}")
    if args.broker is not None and args.broker_port is not None:
        raise ConfigError("--broker-port", "is for our own broker; it cannot go with --broker")
    _check_scheduler(args)
    rec_cls = None
    if args.record is not None:
        need("--record", "mcap", "orjson")
        from sigma_des.record import Recorder
        from sigma_des.record.cli import check_record_path

        check_record_path(args.record)
        from sigma_des.guard import output_file

        output_file(args.record, "--record")  # /proc, a read-only folder: now, not after
        rec_cls = Recorder
    if args.out:  # a bad output location must not cost the whole run
        from sigma_des.outputs import check_out_dir

        if not args.no_plots:
            need("--out", "matplotlib", instead="pass --no-plots")
        check_out_dir(args.out)
    opts = LiveOptions(broker=args.broker, username=args.username, password=password(args),
                       tls_ca=_tls_ca(args),
                       broker_port=args.broker_port, impair=not args.no_impair,
                       step_delay=not args.no_step_delay, max_inflight=args.max_inflight,
                       bundle=args.bundle, record=rec_cls is not None, force=args.force,
                       scheduler=args.scheduler, placement=args.placement)
    with Interrupts() as sig:
        try:
            res, msgs, kept = run_live(sc, methods, opts, progress=not args.no_progress,
                                       on_method=_writer(args) if args.out else None)
        except KeyboardInterrupt:
            print("sigma-des: interrupted before any method finished; broker and hosts stopped",
                  file=sys.stderr)
            return 130
        except (RuntimeError, ConnectionError) as e:
            print(f"sigma-des: live run failed: {e}", file=sys.stderr)
            return 1
        sig.mask()  # the run is over: a signal now must not cut the writing short
        print(res.table())
        if res.interrupted:
            print("interrupted: partial results", file=sys.stderr)
        if args.out:
            _write_out(args, res, msgs, plots=not args.no_plots)
        if rec_cls is not None:
            from sigma_des.live.messages import record_messages

            record_messages(rec_cls, args.record, res, msgs, kept)
            print(f"recorded {args.record}")
    return 130 if res.interrupted else 0


def _tls_ca(args: argparse.Namespace) -> str:
    """The PEM text of ``--tls-ca`` ('' without it)."""
    if args.tls_ca is None:
        return ""
    try:
        text = Path(args.tls_ca).read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError("--tls-ca", f"cannot read {args.tls_ca}: "
                          f"{getattr(e, 'strerror', None) or e}") from None
    if "-----BEGIN CERTIFICATE-----" not in text:
        raise ConfigError("--tls-ca", f"{args.tls_ca} holds no PEM certificate")
    return text


def _check_scheduler(args: argparse.Namespace) -> None:
    """``--scheduler`` and ``--placement``, before anything is written: the scheduler must
    accept connections within 3 s (else exit 2 at once)."""
    if args.scheduler is None:
        if args.placement != "spread":
            raise ConfigError("--placement", "needs --scheduler")
        return
    from sigma_des.extras import need

    need("--scheduler", "distributed", extra="experiments")
    from sigma_des.live.broker import wait_port
    from sigma_des.live.cluster import parse_scheduler
    from sigma_des.live.placement import read_placement

    read_placement(args.placement)
    host, port = parse_scheduler(args.scheduler)
    if not wait_port(host, port, 3.0):
        raise ConfigError("--scheduler", f"no Dask scheduler accepts connections at "
                          f"{host}:{port} (within 3 s)")


def _writer(args: argparse.Namespace) -> Callable[[Results, pd.DataFrame], None]:
    """Write each finished method's results at once (a later signal or crash keeps them)."""
    def write(res: Results, msgs: pd.DataFrame) -> None:
        _write_out(args, res, msgs, plots=False, quiet=True)
    return write


def _write_out(args: argparse.Namespace, res: Results, msgs: pd.DataFrame, plots: bool,
               quiet: bool = False) -> None:
    from sigma_des.live.cpu import write_cpu
    from sigma_des.live.messages import write_messages

    csv_path, json_path = res.write(args.out)
    mpath = write_messages(msgs, Path(args.out))
    cpath = write_cpu(res.live, Path(args.out))
    if quiet:
        return
    print(f"wrote {csv_path}, {csv_path.parent / 'wall.csv'}, {json_path}, {mpath} "
          f"and {cpath}")
    if plots:  # matplotlib was checked before the run
        from sigma_des.plots import write_plots

        paths = write_plots(res, args.out)
        print(f"plots: {', '.join(p.name for p in paths)}")


def password(args: argparse.Namespace) -> str:
    """The MQTT password: ``--password``, else ``--password-file``, else :data:`PASSWORD_ENV`.

    Raises:
        ConfigError: both options given, or the file cannot be read.
    """
    if args.password is not None and args.password_file is not None:
        raise ConfigError("--password-file", "cannot go with --password; give one of them")
    if args.password is not None:
        return str(args.password)
    if args.password_file is not None:
        try:
            text = Path(args.password_file).read_text(encoding="utf-8")
        except OSError as e:
            raise ConfigError("--password-file",
                              f"cannot read {args.password_file}: {e.strerror or e}") from None
        return text.splitlines()[0] if text else ""
    return os.environ.get(PASSWORD_ENV, "")
