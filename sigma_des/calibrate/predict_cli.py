"""The ``sigma-des predict`` and ``sigma-des capacity`` subcommands.

``predict CAL.toml`` prints the calibrated model's prediction of a target (the
calibration with ``--set`` keys, ``--bundle``, ``--add-latency``), every method, each
figure with its interval (:mod:`sigma_des.calibrate.predict`); ``capacity CAL.toml``
the largest N each method holds within the budgets (:mod:`sigma_des.calibrate.capacity`).
Bad input exits 2 naming the option.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tempfile
from pathlib import Path
from typing import IO, Any

from sigma_des.errors import ConfigError

__all__ = ["add_capacity_args", "add_predict_args", "run_capacity", "run_predict"]


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("calibration", metavar="CAL.toml",
                   help="a `sigma-des calibrate --out` scenario (its report CAL.json beside it)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="a target key on the calibrated scenario (repeatable), e.g. "
                   "--set nodes=60 --set hosts=3")
    p.add_argument("--bundle", action="store_true",
                   help="bundled messages (one PUBLISH per host and turn), as live --bundle")
    p.add_argument("--add-latency", type=float, default=0.0, metavar="MS",
                   help="milliseconds added to every host-link crossing, both directions "
                   "(as the live shim's net.host_link.latency above the base's)")
    p.add_argument("--seeds", type=int, default=1, metavar="R",
                   help="DES runs per method (seeds: the scenario's and the next R-1; "
                   "their spread widens the interval; default 1)")
    p.add_argument("--methods", default=None, help="comma-separated (default: the four)")
    p.add_argument("--residuals", default=None, metavar="FILE",
                   help="the validation's residuals.toml (default: the one shipped)")
    p.add_argument("--out", default=None, metavar="DIR", help="write the results here")
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.add_argument("--allow-load", action="store_true",
                   help="predict even from a calibration whose runs ran under load (other "
                   "processes above 25%% of the cores): refused otherwise, its predictions "
                   "of an idle machine being too slow")


def add_predict_args(p: argparse.ArgumentParser) -> None:
    """Arguments of ``predict``."""
    _common(p)


def add_capacity_args(p: argparse.ArgumentParser) -> None:
    """Arguments of ``capacity``."""
    _common(p)
    p.add_argument("--max-missed", type=float, default=0.05, metavar="FRAC",
                   help="largest share of missed frames a size may have (0..1, default 0.05)")
    p.add_argument("--max-latency", type=float, default=None, metavar="MS",
                   help="largest mean state latency (ms; default: no latency budget)")
    p.add_argument("--hosts-rule", default="validation", metavar="RULE",
                   help="hosts for N nodes: validation (max(2, ceil(N/25)), default), fixed "
                   "(the calibration's) or per=K (ceil(N/K))")
    p.add_argument("--n-min", type=int, default=10, metavar="N",
                   help="smallest N tried (default 10)")
    p.add_argument("--n-max", type=int, default=400, metavar="N",
                   help="largest N tried (default 400)")


def _say(quiet: bool) -> Any:
    return None if quiet else (lambda s: print(s, file=sys.stderr, flush=True))


def _check(args: argparse.Namespace) -> tuple[Any, Any, list[str]]:
    from sigma_des.calibrate.campaign import refuse_loaded
    from sigma_des.calibrate.predict import load_calibration, parse_methods
    from sigma_des.outputs import check_out_dir

    methods = parse_methods(args.methods)
    if not math.isfinite(args.add_latency) or not 0.0 <= args.add_latency <= 1000.0:
        raise ConfigError("--add-latency", f"must be in 0..1000 ms, got {args.add_latency}")
    cal, report = load_calibration(args.calibration)
    refuse_loaded(report, cal.deployment.cores, args.allow_load)
    if args.out:
        check_out_dir(args.out)
    return cal, report, methods


def run_predict(args: argparse.Namespace) -> int:
    """Run ``predict``; ConfigError propagates (exit 2)."""
    from sigma_des.calibrate.predict import predict

    cal, report, methods = _check(args)
    with tempfile.TemporaryDirectory(prefix="sigma-des-predict-") as tmp:
        samples = Path(args.out) / "samples" if args.out else Path(tmp)
        pred = predict(cal, report, args.sets, bundle=args.bundle,
                       add_latency_s=args.add_latency / 1e3, seeds=args.seeds,
                       methods=methods, samples_dir=samples, residuals=args.residuals,
                       say=_say(args.no_progress))
    print(f"prediction: N = {pred.scenario.nodes} on {pred.scenario.hosts} hosts, "
          f"{'bundled' if args.bundle else 'per-node'} messages"
          + (f", +{args.add_latency:g} ms per host-link crossing" if args.add_latency else "")
          + f"; state hops x{pred.state_hops[0]:.3g} ({pred.state_hops[1]})")
    print(pred.table())
    if args.out:
        csv_path, json_path = pred.write(args.out)
        print(f"wrote {csv_path} and {json_path}")
    return 0


def run_capacity(args: argparse.Namespace) -> int:
    """Run ``capacity``; ConfigError propagates (exit 2)."""
    from sigma_des.calibrate.capacity import HostsRule, find_capacity
    from sigma_des.calibrate.predict import predict
    from sigma_des.calibrate.target import prepare

    if not (math.isfinite(args.max_missed) and 0.0 <= args.max_missed < 1.0):
        raise ConfigError("--max-missed", f"must be in 0..1 (a share), got {args.max_missed}")
    if args.max_latency is not None and not (math.isfinite(args.max_latency)
                                             and args.max_latency > 0):
        raise ConfigError("--max-latency", f"must be > 0 ms, got {args.max_latency}")
    if not 1 <= args.n_min <= args.n_max <= 5000:
        raise ConfigError("--n-min", f"need 1 <= --n-min <= --n-max <= 5000, got "
                          f"{args.n_min}, {args.n_max}")
    for s in args.sets:
        if s.split("=", 1)[0].strip() in ("nodes", "hosts"):
            raise ConfigError("--set", f"{s.split('=', 1)[0]} is what capacity searches; "
                              "use --n-min/--n-max and --hosts-rule")
    cal, report, methods = _check(args)
    rule = HostsRule.parse(args.hosts_rule, cal.hosts)
    say = _say(args.no_progress)
    caps = []
    with tempfile.TemporaryDirectory(prefix="sigma-des-capacity-") as tmp:
        # the rate a method must hold is the target's (a --set f_trig=... changes it)
        f_trig = prepare(cal, report, [*args.sets, f"nodes={args.n_min}",
                                       f"hosts={rule.hosts(args.n_min)}"],
                         bundle=args.bundle, add_latency_s=args.add_latency / 1e3,
                         samples_dir=Path(tmp)).f_trig
        for m in methods:
            def at(n: int, m: str = m) -> Any:
                p = predict(cal, report, [*args.sets, f"nodes={n}", f"hosts={rule.hosts(n)}"],
                            bundle=args.bundle, add_latency_s=args.add_latency / 1e3,
                            seeds=args.seeds, methods=[m], samples_dir=Path(tmp),
                            residuals=args.residuals)
                iv = p.intervals[m]
                if say is not None:
                    say(f"capacity {m}: N = {n} on {rule.hosts(n)} hosts: missed "
                        f"{100 * iv['missed_frac'].mean:.1f} %, latency "
                        f"{iv['latency_state_mean'].mean:.3g} ms, rate "
                        f"{iv['trigger_rate_hz'].mean:.4g} Hz ({p.regimes[m]})")
                return iv
            caps.append(find_capacity(m, at, args.n_min, args.n_max, f_trig,
                                      args.max_missed, args.max_latency))
    _print(caps, args)
    if args.out:
        _write(caps, Path(args.out), args, f_trig)
    return 0


def _n(x: int | None, beyond: int, below: int) -> str:
    return f"> {beyond}" if x == beyond else (f"< {below}" if x is None else str(x))


def _print(caps: list[Any], args: argparse.Namespace) -> None:
    from sigma_des.tables import text_table

    budget = f"missed <= {100 * args.max_missed:g} %, rate held" + (
        f", latency <= {args.max_latency:g} ms" if args.max_latency is not None else "")
    print(f"capacity ({'bundled' if args.bundle else 'per-node'} messages; {budget}; "
          f"hosts {args.hosts_rule}):")
    rows = [["method", "capacity N", "interval", "first failing N", "predictions"]]
    for c in caps:
        fmt = lambda x: _n(x, args.n_max, args.n_min)  # noqa: E731
        held = c.capacity == args.n_max
        rows.append([c.method, fmt(c.capacity), f"[{fmt(c.lo)}, {fmt(c.hi)}]",
                     "-" if held else str(c.first_failing), str(len(c.points))])
    print(text_table(rows))


def _write(caps: list[Any], out: Path, args: argparse.Namespace, f_trig: float) -> None:
    from sigma_des.calibrate.capacity import plot
    from sigma_des.calibrate.target import FIGURES
    from sigma_des.outputs import write_files

    def cap_csv(fh: IO[str]) -> None:
        w = csv.writer(fh)
        w.writerow(["method", "capacity", "lo", "hi", "first_failing", "evaluated"])
        for c in caps:
            w.writerow([c.method, c.capacity, c.lo, c.hi, c.first_failing,
                        " ".join(map(str, c.evaluated))])

    def points_csv(fh: IO[str]) -> None:
        w = csv.writer(fh)
        w.writerow(["method", "nodes", "metric", "mean", "sd", "lo", "hi"])
        for c in caps:
            for n, ivs in c.points.items():
                for k in FIGURES:
                    iv = ivs[k]
                    w.writerow([c.method, n, k, iv.mean, iv.sd, iv.lo, iv.hi])

    def summ(fh: IO[str]) -> None:
        fh.write(json.dumps({"max_missed": args.max_missed, "max_latency_ms": args.max_latency,
                             "f_trig_hz": f_trig,
                             "hosts_rule": args.hosts_rule, "bundle": args.bundle,
                             "methods": {c.method: {"capacity": c.capacity, "lo": c.lo,
                                                    "hi": c.hi, "first_failing": c.first_failing}
                                         for c in caps}}, indent=2) + "\n")

    paths = write_files(out, {"capacity.csv": cap_csv, "points.csv": points_csv,
                              "summary.json": summ})
    plot(caps, out / "capacity.png", args.max_missed, args.max_latency, f_trig)
    print(f"wrote {', '.join(str(p) for p in paths)} and {out / 'capacity.png'}")
