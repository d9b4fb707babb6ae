"""The engine benchmark's driver: command line, the run over node counts, notes, CSV.

``experiments/bench_engine.py`` is a front end to this module: :func:`bench_parser`
and :func:`bench_options` turn its command line into :class:`BenchOptions`,
:func:`run_bench` runs every case of every node count (each in a fresh process, via
:func:`sigma_lab.studies.engine_bench.run_fresh`) and returns the rows, the metric
checks and the notes, :func:`sigma_lab.studies.engine_tables.report_text` formats
them and :func:`write_csv` writes the rows. What a case is and how it is compared is
:mod:`sigma_lab.studies.engine_bench`; see ``lab/record/BENCHMARKS.md``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import platform
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sigma_lab.studies.engine_bench import (
    ALL_METHODS,
    COLUMNS,
    NODES_PER_HOST,
    Case,
    Check,
    annotate,
    baseline_estimate_s,
    make_row,
    overrides_for,
    plan,
    run_fresh,
)
from sigma_lab.studies.engine_norm import (
    REF_CPU_PER_SIM_S,
    REF_NODES,
    REF_SIM_S,
    normalise,
    reference_row,
)

__all__ = [
    "BenchOptions",
    "Runner",
    "bench_options",
    "bench_parser",
    "echo",
    "exit_status",
    "header_lines",
    "machine_info",
    "node_notes",
    "parse_methods",
    "parse_nodes",
    "run_bench",
    "run_node",
    "write_csv",
]

#: What runs one case: ``(impl, method, overrides, cpu, start_method) -> result dict``
#: (:func:`~sigma_lab.studies.engine_bench.run_fresh`; tests pass a fake).
Runner = Callable[[str, str, list[str], int | None, str], dict[str, Any]]


def echo(line: str) -> None:
    """Print a progress line at once (a long benchmark shows every finished case)."""
    print(line, flush=True)


@dataclass(frozen=True)
class BenchOptions:
    """One benchmark invocation (the command line of ``experiments/bench_engine.py``).

    Attributes:
        nodes: node counts, in running order.
        methods: methods timed on the full scenario.
        duration: simulated seconds per case.
        baseline: whether the process-per-message baseline runs.
        events_cap: at ``n >= large_n`` the events cases simulate
            ``min(duration, events_cap)``.
        baseline_cap: the same for the baseline.
        baseline_max_n: the baseline is skipped above this N.
        large_n: where the caps start.
        sets: scenario overrides applied to every case.
        cpu: the CPU every case is pinned to (None: not pinned).
        start_method: ``forkserver`` or ``spawn`` (see ``run_fresh``).
        out: the CSV file the rows are written to (None: none).
        reference: measure the baseline that normalises the figures (``ref_nodes``
            nodes, restricted, ``ref_sim_s`` s; reused if a case of the run is it).
        ref_nodes: its node count.
        ref_sim_s: its simulated seconds.
    """

    nodes: tuple[int, ...]
    methods: tuple[str, ...]
    duration: float = 5.0
    baseline: bool = True
    events_cap: float = 2.0
    baseline_cap: float = 2.0
    baseline_max_n: int = 1000
    large_n: int = 1000
    sets: tuple[str, ...] = ()
    cpu: int | None = None
    start_method: str = "forkserver"
    out: Path | None = None
    reference: bool = True
    ref_nodes: int = REF_NODES
    ref_sim_s: float = REF_SIM_S


def machine_info(cwd: Path) -> str:
    """CPU model, logical CPUs, Python and SimPy versions and the git commit of ``cwd``."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    import simpy

    return (
        f"{cpu}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, "
        f"SimPy {simpy.__version__}; commit {commit or '?'}"
    )


def bench_parser(description: str) -> argparse.ArgumentParser:
    """The benchmark's command line (``--help`` shows ``description``)."""
    p = argparse.ArgumentParser(description=description)
    add = p.add_argument
    add("--nodes", default="200,1000,10000", help="comma-separated node counts")
    add("--duration", type=float, default=5.0, help="simulated seconds per case")
    add("--methods", default="bides", help="methods timed on the full scenario: "
        f"comma-separated, or 'all' ({','.join(ALL_METHODS)})")
    add("--baseline", action=argparse.BooleanOptionalAction, default=True,
        help="also run the process-per-message SimPy baseline (restricted scenario)")
    add("--events-cap", type=float, default=2.0,
        help="at N >= --large-n the events cases simulate min(duration, this)")
    add("--baseline-cap", type=float, default=2.0,
        help="at N >= --large-n the baseline simulates min(duration, this)")
    add("--baseline-max-n", type=int, default=1000,
        help="skip the baseline above this N (it would take many minutes)")
    add("--large-n", type=int, default=1000, help="see --events-cap, --baseline-cap")
    add("--quick", action="store_true", help="tiny run: N = 10,50, 1 s (for tests)")
    add("--set", action="append", default=[], metavar="KEY=VALUE",
        help="scenario override applied to every case (repeatable)")
    add("--cpu", type=int, default=None, help="pin every case to this CPU")
    add("--start-method", choices=("forkserver", "spawn"), default="forkserver",
        help="how each case's fresh process is started (default: forkserver)")
    add("--out", type=Path, default=None, help="write the rows to this CSV file")
    add("--reference", action=argparse.BooleanOptionalAction, default=True,
        help="also run the SimPy baseline that normalises every figure (N = --ref-nodes, "
        "restricted, --ref-duration s; reused if the run has that case)")
    add("--ref-nodes", type=int, default=REF_NODES, help="node count of the reference")
    add("--ref-duration", type=float, default=REF_SIM_S,
        help="simulated seconds of the reference")
    return p


def parse_nodes(text: str) -> list[int]:
    """``"200,1000"`` -> ``[200, 1000]`` (blank items skipped).

    Raises:
        ValueError: an item is not an integer (the message names the option).
    """
    try:
        return [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"--nodes: not a comma-separated list of integers: {text!r}") from None


def parse_methods(text: str) -> list[str]:
    """``"all"`` or a comma list of methods, checked against ``ALL_METHODS``.

    Raises:
        ValueError: an unknown method (every one named, with the allowed ones).
    """
    if text.strip() == "all":
        return list(ALL_METHODS)
    methods = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in methods if m not in ALL_METHODS]
    if bad:
        raise ValueError(
            f"--methods: unknown {', '.join(bad)}; allowed: {','.join(ALL_METHODS)} or all"
        )
    return methods


def bench_options(p: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> BenchOptions:
    """Parse ``argv`` with ``p`` (:func:`bench_parser`); a bad value exits 2 via ``p.error``.

    ``--quick`` is N = 10,50 for 1 s.
    """
    a = p.parse_args(argv)
    if a.quick:  # the reference is then the N = 50 baseline case itself
        a.nodes, a.duration, a.ref_nodes, a.ref_duration = "10,50", 1.0, 50, 1.0
    try:
        nodes = parse_nodes(a.nodes)
        methods = parse_methods(a.methods)
    except ValueError as err:
        p.error(str(err))
    if a.ref_nodes < 1:
        p.error("--ref-nodes must be >= 1")
    for opt in ("duration", "events_cap", "baseline_cap", "ref_duration"):
        if not getattr(a, opt) > 0:
            p.error(f"--{opt.replace('_', '-')} must be > 0")
    return BenchOptions(
        tuple(nodes), tuple(methods), a.duration, a.baseline, a.events_cap, a.baseline_cap,
        a.baseline_max_n, a.large_n, tuple(a.set), a.cpu, a.start_method, a.out,
        a.reference, a.ref_nodes, a.ref_duration,
    )


def header_lines(opts: BenchOptions, machine: str) -> list[str]:
    """The two lines printed before the first case: machine, scenario and overrides."""
    sets = list(opts.sets) or "none"
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return [
        f"sigma_des engine benchmark: cohort vs events vs baseline  ({machine})",
        f"scenario: defaults + {NODES_PER_HOST} nodes/host, duration {opts.duration:g} s "
        f"(warm-up {min(1.0, 0.2 * opts.duration):g} s); overrides: {sets}",
        f"load average at the start (1, 5, 15 min): {load}",
    ]


def node_notes(
    opts: BenchOptions, n: int, rows: list[dict[str, Any]], log: Callable[[str], None] = echo
) -> list[str]:
    """The notes on the caps and the skipped baseline at ``n`` nodes (printed at the end).

    The skip note is also logged at once (the rows so far give its time estimate).
    """
    notes: list[str] = []
    big = n >= opts.large_n
    if big and opts.events_cap < opts.duration:
        notes.append(
            f"N={n}: the events engine (and its cohort twin) simulates {opts.events_cap:g} s "
            f"instead of {opts.duration:g} s (--events-cap)"
        )
    with_baseline = opts.baseline and n <= opts.baseline_max_n
    if opts.baseline and not with_baseline:
        dur_b = min(opts.duration, opts.baseline_cap) if big else opts.duration
        est = baseline_estimate_s(rows, n, dur_b)
        took = f"> {math.floor(est / 60)} minutes" if est >= 120 else f"~{est:.0f} s"
        msg = (
            f"N={n}: baseline skipped (--baseline-max-n {opts.baseline_max_n}): the baseline "
            f"would take {took} ({dur_b:g} s simulated, linear in N)"
        )
        notes.append(msg)
        log("  " + msg)
    elif with_baseline and big and opts.baseline_cap < opts.duration:
        notes.append(
            f"N={n}: the baseline (and its cohort twin) simulates {opts.baseline_cap:g} s "
            f"instead of {opts.duration:g} s (--baseline-cap)"
        )
    return notes


def run_node(
    opts: BenchOptions,
    n: int,
    rows: list[dict[str, Any]],
    notes: list[str],
    run: Runner = run_fresh,
    log: Callable[[str], None] = echo,
) -> None:
    """Run every case of ``n`` nodes with ``run``, appending rows and fallback notes."""
    with_baseline = opts.baseline and n <= opts.baseline_max_n
    cap_b = opts.baseline_cap if with_baseline else None
    cases = plan(n, opts.methods, opts.duration, opts.events_cap, cap_b, opts.large_n)
    for case in cases:
        ov = overrides_for(n, case.sim_s, case.scenario == "restricted", opts.sets, case.impl)
        res = run(case.impl, case.method, ov, opts.cpu, opts.start_method)
        rows.append(make_row(case, n, res))
        log(
            f"  N={n:<6} {case.impl + ('~' if case.role == 'twin' else ''):<9} "
            f"{case.method:<8} {case.scenario:<10} {case.sim_s:5g} s sim "
            f"{res['wall_s']:9.2f} s wall  ({res['engine_used']})"
        )
        if res.get("kernels_loaded"):  # a one-off cost the warm-up should have taken
            notes.append(f"N={n} {case.impl} {case.method} {case.scenario}: "
                         f"{res['kernels_loaded']} kernel(s) loaded in the timed run")
        if res["fallback"]:
            note = f"{case.method} on the {case.scenario} scenario: cohort fell back to the "
            note += f"per-message engine: {res['fallback']}"
            if note not in notes:
                notes.append(note)


def _baseline_supported(opts: BenchOptions) -> str:
    """Why the baseline cannot run the scenario of ``opts`` ("" if it can)."""
    from sigma_des.config import load
    from sigma_lab.reference.process_model import Unsupported, check_supported

    try:
        check_supported(load(overrides=overrides_for(10, opts.duration, True, opts.sets)))
    except Unsupported as err:
        return str(err)
    return ""


def run_bench(
    opts: BenchOptions, run: Runner = run_fresh, log: Callable[[str], None] = echo
) -> tuple[list[dict[str, Any]], list[Check], list[str]]:
    """Run every node count of ``opts``; return the rows, the metric checks and the notes.

    The baseline is dropped, with a note, when it does not support the scenario
    (``--set`` can make one it does not reproduce).
    """
    notes: list[str] = []
    if opts.baseline:
        why = _baseline_supported(opts)
        if why:
            notes.append(f"no baseline: {why}")
            opts = dataclasses.replace(opts, baseline=False)
    rows: list[dict[str, Any]] = []
    for n in opts.nodes:
        notes += node_notes(opts, n, rows, log)
        run_node(opts, n, rows, notes, run, log)
    checks = annotate(rows)
    if opts.reference:
        notes.append(reference_note(opts, rows, run, log))
    return rows, checks, notes


def reference_note(
    opts: BenchOptions, rows: list[dict[str, Any]], run: Runner = run_fresh,
    log: Callable[[str], None] = echo,
) -> str:
    """Normalise ``rows`` by the reference baseline (run here unless a row is it); the note.

    The reference is the default restricted scenario, whatever ``--set`` says (it
    measures the machine, not the scenario): a baseline case of the run is reused only
    without ``--set``. It runs with ``--no-baseline`` too; ``--no-reference`` skips it.
    The reference case is appended to ``rows`` with the role ``reference``.
    """
    ref = None if opts.sets else reference_row(rows, opts.ref_nodes, opts.ref_sim_s)
    if ref is None:
        case = Case("baseline", "none", "restricted", opts.ref_sim_s, "reference")
        ov = overrides_for(opts.ref_nodes, opts.ref_sim_s, True, (), case.impl)
        res = run(case.impl, case.method, ov, opts.cpu, opts.start_method)
        ref = make_row(case, opts.ref_nodes, res)
        rows.append(ref)
        log(f"  N={opts.ref_nodes:<6} baseline  none     reference  {opts.ref_sim_s:5g} s sim "
            f"{res['wall_s']:9.2f} s wall  (normalises the figures)")
    factor = normalise(rows, ref)
    return (
        f"normalised figures (norm columns, targets): CPU-s per simulated s x {factor:.3f} "
        f"= {REF_CPU_PER_SIM_S:g} / {float(ref['cpu_per_sim_s']):.3f}, the CPU-s/s of the "
        f"SimPy baseline of this run (N = {opts.ref_nodes}, restricted, {opts.ref_sim_s:g} s; "
        f"load {float(ref['load1']):.2f}) against {REF_CPU_PER_SIM_S:g} on the reference "
        "machine of the targets"
    )


def write_csv(rows: list[dict[str, Any]], path: Path) -> None:
    """The rows as CSV with the columns ``COLUMNS`` (the private ``_metrics`` left out)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)


def exit_status(checks: Sequence[Check]) -> tuple[int, str]:
    """The benchmark's exit status and its last line: 1 and the count if a check failed.

    A failed check is a cohort run whose metrics differ from the events run's at
    all, or from the baseline's beyond ``BASELINE_RTOL``; 0 and "" otherwise.
    """
    failed = [c for c in checks if not c.ok]
    if failed:
        return 1, f"FAILED: {len(failed)} metric check(s) (see 'Metric checks' above)"
    return 0, ""
