"""The ``sigma-des calibrate`` subcommand: fit the DES to a live run, write a scenario.

``calibrate`` fits DES parameters from a ``sigma-des live --out`` directory (or an
MCAP recording), writes a scenario TOML that ``compare`` runs and its report (JSON),
with the in-sample check and warnings about what it could not fit.
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path
from typing import IO, Any

from sigma_des.errors import ConfigError

__all__ = ["add_calibrate_args", "run_calibrate"]


def add_calibrate_args(p: argparse.ArgumentParser) -> None:
    """Add the arguments of ``calibrate`` to its subparser ``p``."""
    p.add_argument("source", nargs="+", metavar="RUN",
                   help="one or more `sigma-des live --out` directories (or MCAP recordings) "
                   "of one scenario: per node and bundled, several sizes; each parameter "
                   "comes from the runs that show it (the report says which)")
    p.add_argument("--background", type=float, default=0.0, metavar="CORES",
                   help="deployment.background of the calibrated scenario: the cores' worth "
                   "of CPU other processes use on the TARGET machine (default 0; the "
                   "calibration runs' own background is measured, taken out of the fit "
                   "and reported, never carried into predictions)")
    p.add_argument("--out", default=None, metavar="SCENARIO.toml",
                   help="write the calibrated scenario here, the report next to it as "
                   "SCENARIO.json (default: print the scenario)")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="fit even when hosts' per-node rows are missing (with a warning)")
    p.add_argument("--hold-tol", type=float, default=None, metavar="SECONDS",
                   help="a delivery this close after the previous one on its connection "
                   "counts as held behind it when latencies are de-queued (default 1e-4; "
                   "0: keep the measured latencies)")
    p.add_argument("--no-check", action="store_true",
                   help="skip the in-sample check (the calibrated DES re-running the live run)")
    p.add_argument("--one-thread", action="store_true",
                   help="fit each process as one thread even when the live run recorded its "
                   "threads apart (default: the loop and paho's network thread apart; "
                   "docs/concepts/deployment.md, 'The network thread')")
    p.add_argument("--runq-growth", action="store_true",
                   help="every process's run-queue wait grows with the DES machine's load "
                   "(Erlang C; default: the broker's alone grows, the hosts' and the "
                   "server's measured waits per CPU second are kept; "
                   "docs/concepts/deployment.md, 'Run-queue waits')")
    p.add_argument("--no-match", action="store_true",
                   help="keep the fitted hop latencies as they are (default: rescale each "
                   "direction's until the DES re-predicts the run's mean state and trigger "
                   "latency within 3 %%; docs/concepts/live-and-calibration.md)")


def _put(body: str, fh: IO[str]) -> None:
    fh.write(body)


def run_calibrate(args: argparse.Namespace) -> int:
    """Run ``calibrate``; ConfigError propagates (exit 2). Warnings go to stderr."""
    from sigma_des.calibrate.campaign import (
        check_combinable,
        run_info,
        under_load_warning,
        with_background,
    )
    from sigma_des.calibrate.dequeue import HOLD_TOL
    from sigma_des.calibrate.fit import calibrate
    from sigma_des.guard import input_file, output_file

    sources = [Path(s) for s in args.source]
    tol = HOLD_TOL if args.hold_tol is None else args.hold_tol
    for source in sources:
        if not source.is_dir():
            input_file(source, str(source), "live run directory, messages.csv.gz or MCAP "
                       "recording")
    if len(set(sources)) != len(sources):
        raise ConfigError("RUN", "a run is named twice")
    infos = [run_info(s) for s in sources]
    if len(sources) > 1:
        check_combinable(infos)
    if args.out:  # a bad output location must cost nothing: checked before the fit
        output_file(args.out, "--out")
        output_file(Path(args.out).with_suffix(".json"), "--out")
    out_dir = Path(args.out).parent if args.out else (sources[0] if sources[0].is_dir()
                                                      else sources[0].parent)
    fits = []
    for i, source in enumerate(sources):
        files = (out_dir / f"run{i + 1}") if len(sources) > 1 else (
            Path(args.out).parent if args.out else None)
        if files is not None:
            files.mkdir(parents=True, exist_ok=True)
        sc_i, rep_i = calibrate(source, files, strict=not args.allow_incomplete, hold_tol=tol,
                                threads=not args.one_thread, runq_growth=args.runq_growth)
        if "background_cores_measured" in rep_i:  # the fit's own figure, from cpu.csv
            infos[i]["background"] = float(rep_i["background_cores_measured"])
            infos[i]["cores"] = int(rep_i.get("deployment_cores", infos[i]["cores"]))
        fits.append((sc_i, rep_i, infos[i]))
    sc, report, primary = _combined(fits, out_dir)
    if not args.no_match:
        from sigma_des.calibrate.match import match_hops

        sc, matched = match_hops(sc, sources[primary], out_dir)
        report.update(matched)
        bundled = _match_bundled(sc, report, fits, sources, primary)
        report.update(bundled)
        if "bundle_hop_run" in bundled:
            report.setdefault("parameter_sources", {})[
                "bundled targets' state-hop factor"] = bundled["bundle_hop_run"].split(", ")
        if "bundle_hop_warning" in bundled:
            report["warnings"].append(bundled["bundle_hop_warning"])
    if not args.no_check:
        rows, warn = _in_sample(sc, report, fits, sources, primary)
        report["in_sample"] = rows
        report["warnings"] += warn
    report["warnings"] += [w for w in map(under_load_warning, infos) if w]
    report["background_cores_of_runs"] = {inf["name"]: inf["background"] for inf in infos}
    sc = with_background(sc, args.background)
    report["deployment_background_cores"] = sc.deployment.background
    report["background_note"] = (
        "deployment.background is the target machine's (calibrate --background, default 0): "
        "the calibration runs' own background was taken out of the fit")
    _write_out(args, sc, report)
    return 0


def _write_out(args: argparse.Namespace, sc: Any, report: dict[str, Any]) -> None:
    """Write (or print) the calibrated scenario, its report and sample files."""
    import json

    from sigma_des.calibrate.fit import calibrated_toml, remove_files, report_lines, sample_files
    from sigma_des.guard import atomic_write

    text = calibrated_toml(sc, report)
    if args.out:
        out = Path(args.out)
        rep = out.with_suffix(".json")
        rep_text = json.dumps(report, indent=2, default=float) + "\n"
        written = sample_files(sc)  # the set is the samples, the scenario, the report
        try:
            for path, body in ((out, text), (rep, rep_text)):
                atomic_write(path, partial(_put, body))
                written.append(path)
        except ConfigError:
            remove_files(written)
            raise
        _warn(report["warnings"])  # after the writes: a failed one is then the one line
        print(f"wrote {out} and {rep}")
        for line in report_lines(report):
            if not line.startswith("warning: "):
                print(f"  {line}")
    else:
        _warn(report["warnings"])
        sys.stdout.write(text)


def _combined(fits: list[Any], out_dir: Path) -> tuple[Any, dict[str, Any], int]:
    """One run's fit as it is; several combined (:func:`~sigma_des.calibrate.campaign.combine`)."""
    if len(fits) == 1:
        return fits[0][0], fits[0][1], 0
    from sigma_des.calibrate.campaign import combine

    return combine(fits, out_dir)


def _match_bundled(sc: Any, report: dict[str, Any], fits: list[Any], sources: list[Path],
                   primary: int) -> dict[str, Any]:
    """A campaign whose hops were matched on a per-node run and that has a bundled run:
    the bundled targets' state-hop factor matched on its first bundled run in name order
    (whatever order the runs were given in), against the mean of the bundled runs of
    that run's size and hosts (repeats; :func:`~sigma_des.calibrate.match.match_bundled`);
    nothing otherwise (the hops already are a bundled run's, or no bundled run shows the
    excess)."""
    from sigma_des.calibrate.match import match_bundled

    bundled = sorted((i for i, (_s, _r, info) in enumerate(fits) if info["bundle"]),
                     key=lambda i: str(fits[i][2]["name"]))
    if not bundled or fits[primary][2]["bundle"]:
        return {}
    i = bundled[0]
    own = fits[i][0]
    same = [j for j in bundled if (fits[j][0].nodes, fits[j][0].hosts) == (own.nodes, own.hosts)]
    return match_bundled(sc, report, own, [sources[j] for j in same],
                         ", ".join(fits[j][2]["name"] for j in same))


def _in_sample(sc: Any, report: dict[str, Any], fits: list[Any], sources: list[Path],
               primary: int) -> tuple[list[dict[str, Any]], list[str]]:
    """The in-sample check on every run: the calibrated scenario prepared for the run
    (its size, hosts, window, seed, message mode) with the run's own background."""
    from sigma_des.calibrate.insample import in_sample
    from sigma_des.calibrate.target import for_run

    rows: list[dict[str, Any]] = []
    warn: list[str] = []
    for i, (own, _rep, info) in enumerate(fits):
        target = sc if len(fits) == 1 else for_run(sc, report, own, bundle=bool(info["bundle"]))
        r, w = in_sample(target, sources[i])
        rows += [{**x, "run": info["name"]} for x in r]
        warn += [f"{info['name']}: {x}" if len(fits) > 1 else x for x in w]
    return rows, warn


def _warn(warnings: list[str]) -> None:
    for w in warnings:
        print(f"sigma-des: warning: {w}", file=sys.stderr)
