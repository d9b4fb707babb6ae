"""studies/engine_driver.py and engine_tables.report_text: the engine benchmark's driver.

Every case here is run by a fake runner (no simulation): the driver's bookkeeping,
notes, checks and exit status are computed from given numbers.
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from typing import Any

import pytest
from sigma_lab.studies.engine_bench import COLUMNS, max_rel_diff
from sigma_lab.studies.engine_driver import (
    BenchOptions,
    bench_options,
    bench_parser,
    exit_status,
    header_lines,
    node_notes,
    parse_methods,
    parse_nodes,
    run_bench,
    run_node,
    write_csv,
)
from sigma_lab.studies.engine_tables import report_text

METRICS = {"aoi_mean": 15.0, "aoi_p99": 20.0, "latency_state_mean": 0.5}


class FakeRunner:
    """Returns fixed results per impl; ``differ`` changes one metric of one impl."""

    def __init__(self, differ: tuple[str, str, float] | None = None, fallback: str = "") -> None:
        self.differ = differ
        self.fallback = fallback
        self.calls: list[tuple[str, str, list[str], int | None, str]] = []

    def __call__(
        self, impl: str, method: str, ov: list[str], cpu: int | None, start: str
    ) -> dict[str, Any]:
        self.calls.append((impl, method, ov, cpu, start))
        sim_s = float(next(o for o in ov if o.startswith("duration=")).split("=")[1])
        metrics = dict(METRICS)
        if self.differ is not None and self.differ[0] == impl:
            metrics[self.differ[1]] = self.differ[2]
        wall = {"cohort": 0.5, "events": 1.0, "baseline": 4.0}[impl] * sim_s
        return {"sim_s": sim_s, "wall_s": wall, "cpu_s": wall, "events": 1000,
                "peak_rss_mb": 100.0, "engine_used": impl,
                "fallback": self.fallback if impl == "cohort" else "", "metrics": metrics}


def _opts(**kw: Any) -> BenchOptions:
    base: dict[str, Any] = {"nodes": (10,), "methods": ("bides",), "duration": 1.0,
                            "reference": False}
    return BenchOptions(**(base | kw))


def test_reference_baseline_normalises_every_figure_and_sets_the_targets() -> None:
    fake = FakeRunner()  # CPU-s/s: cohort 0.5, events 1, baseline 4
    lines: list[str] = []
    rows, _checks, notes = run_bench(_opts(reference=True), fake, lines.append)
    ref = rows[-1]
    # not a case of the run (N = 10): run on its own, default restricted scenario
    assert (ref["impl"], ref["role"], ref["n"], ref["sim_s"]) == ("baseline", "reference",
                                                                 1000, 2.0)
    assert fake.calls[-1][2] == ["nodes=1000", "hosts=50", "duration=2.0", "warmup=0.4",
                                 "commands.enabled=false"]
    assert "(normalises the figures)" in lines[-1]
    # factor 10 / 4 = 2.5: the cohort's 0.5 CPU-s/s is 1.25 on the reference machine
    cohort = rows[0]
    assert (cohort["cpu_per_sim_s_norm"], cohort["x_realtime_norm"]) == (1.25, 0.8)
    assert ref["cpu_per_sim_s_norm"] == 10.0
    assert notes[-1].startswith("normalised figures (norm columns, targets): CPU-s per "
                                "simulated s x 2.500 = 10 / 4.000")
    # a case of the run that is the reference is reused (no --set): no extra run
    fake = FakeRunner()
    rows, _checks, _notes = run_bench(
        _opts(reference=True, nodes=(1000,), duration=2.0), fake, lambda _line: None)
    assert [r["role"] for r in rows].count("reference") == 0
    assert len(fake.calls) == len(rows)
    assert rows[0]["x_realtime_norm"] == 0.8
    # the targets: N = 1000 full BiDES 20x (10x for a 1 s run), restricted 50x
    text = report_text(rows, _checks, _notes)
    assert ">= 20x" in text and ">= 50x" in text and ">= 300x" in text
    assert [r["target_x"] for r in rows if r["impl"] == "cohort" and r["role"] == "main"] == [
        20.0, 50.0]
    one = run_bench(_opts(reference=True, nodes=(1000,)), FakeRunner(), lambda _l: None)[0]
    assert one[0]["target_x"] == 10.0
    assert all(math.isnan(r["cpu_per_sim_s_norm"])
               for r in run_bench(_opts(), FakeRunner(), lambda _l: None)[0])


def test_max_rel_diff_names_the_one_metric_that_differs() -> None:
    a = {"aoi_mean": 15.0, "aoi_p99": 20.0, "x": 1.0}
    b = {"aoi_mean": 15.0, "aoi_p99": 25.0, "x": 1.0}
    assert max_rel_diff(a, b, sorted(a)) == (0.2, "aoi_p99")  # |20 - 25| / 25
    assert max_rel_diff(a, a, sorted(a)) == (0.0, "")
    # missing on one side is NaN: differs; NaN on both sides is equal
    assert max_rel_diff(a, {"aoi_mean": 15.0}, ["aoi_mean", "x"]) == (math.inf, "x")
    assert max_rel_diff({"y": math.nan}, {"y": math.nan}, ["y"]) == (0.0, "")


def test_identity_check_fails_the_run_on_one_differing_metric() -> None:
    fake = FakeRunner(differ=("events", "aoi_p99", 20.0 * (1 + 1e-15)))
    rows, checks, notes = run_bench(_opts(baseline=False), fake, lambda _line: None)
    assert notes == []
    assert [(c.scenario, c.method, c.other, c.metric, c.ok) for c in checks] == [
        ("full", "bides", "events", "aoi_p99", False),
        ("restricted", "none", "events", "aoi_p99", False),
    ]
    assert checks[0].diff == pytest.approx(1e-15, rel=0.2)
    events_full = rows[1]
    assert (events_full["impl"], events_full["max_rel_diff_metric"]) == ("events", "aoi_p99")
    assert exit_status(checks) == (
        1, "FAILED: 2 metric check(s) (see 'Metric checks' above)")
    text = report_text(rows, checks, notes)
    assert text.count("DIFFERENT") == 2 and "Metrics, cohort vs baseline" not in text


def test_baseline_within_tolerance_passes_beyond_it_fails() -> None:
    ok = FakeRunner(differ=("baseline", "aoi_mean", 15.0 * (1 + 1e-12)))
    _rows, checks, _notes = run_bench(_opts(), ok, lambda _line: None)
    assert [(c.other, c.metric, c.ok) for c in checks] == [
        ("events", "", True), ("events", "", True), ("baseline", "aoi_mean", True)]
    assert exit_status(checks) == (0, "")
    bad = FakeRunner(differ=("baseline", "latency_state_mean", 0.5 * (1 + 1e-6)))
    rows, checks, _notes = run_bench(_opts(), bad, lambda _line: None)
    assert [(c.other, c.metric, c.ok) for c in checks][-1] == (
        "baseline", "latency_state_mean", False)
    assert exit_status(checks)[0] == 1
    assert "DIFFERENT (> 1e-09)" in report_text(rows, checks, [])
    # speed-ups from the fake wall times: events 2x, baseline 8x the cohort's
    cohort = rows[2]
    assert (cohort["scenario"], cohort["ratio_vs_events"], cohort["ratio_vs_baseline"]) == (
        "restricted", 2.0, 8.0)


def test_run_node_logs_each_case_and_notes_a_fallback_once() -> None:
    lines: list[str] = []
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    fake = FakeRunner(fallback="no support")
    opts = _opts(baseline=False, cpu=1, start_method="spawn", sets=("a.b=1",))
    run_node(opts, 10, rows, notes, fake, lines.append)
    assert [r["impl"] for r in rows] == ["cohort", "events", "cohort", "events"]
    assert lines[0] == (
        "  N=10     cohort    bides    full           1 s sim      0.50 s wall  (cohort)")
    assert notes == [
        "bides on the full scenario: cohort fell back to the per-message engine: no support",
        "none on the restricted scenario: cohort fell back to the per-message engine: "
        "no support",
    ]
    impl, method, ov, cpu, start = fake.calls[2]
    assert (impl, method, cpu, start) == ("cohort", "none", 1, "spawn")
    assert ov == ["nodes=10", "hosts=1", "duration=1.0", "warmup=0.2",
                  "commands.enabled=false", "a.b=1", 'engine="cohort"']


def test_node_notes_caps_and_the_skipped_baseline_estimate() -> None:
    opts = _opts(duration=5.0, events_cap=2.0, baseline_cap=1.0, baseline_max_n=1000)
    logged: list[str] = []
    assert node_notes(opts, 200, [], logged.append) == []
    assert node_notes(opts, 1000, [], logged.append) == [
        "N=1000: the events engine (and its cohort twin) simulates 2 s instead of 5 s "
        "(--events-cap)",
        "N=1000: the baseline (and its cohort twin) simulates 1 s instead of 5 s "
        "(--baseline-cap)",
    ]
    assert logged == []
    # the estimate: linear in N from the largest measured baseline (0.02 s/node/sim s)
    rows = [{"impl": "baseline", "n": 100, "wall_per_sim_s": 2.0}]
    skip = ("N=10000: baseline skipped (--baseline-max-n 1000): the baseline would take "
            "> 3 minutes (1 s simulated, linear in N)")
    assert node_notes(opts, 10000, rows, logged.append)[1] == skip
    assert logged == ["  " + skip]
    short = node_notes(_opts(baseline_max_n=5), 10, rows, logged.append)
    assert short == ["N=10: baseline skipped (--baseline-max-n 5): the baseline would take "
                     "~0 s (1 s simulated, linear in N)"]


def test_unsupported_baseline_is_dropped_with_a_note() -> None:
    fake = FakeRunner()
    opts = _opts(sets=('net.transport="datagram"',))
    rows, _checks, notes = run_bench(opts, fake, lambda _line: None)
    assert notes == ["no baseline: baseline does not support: transport 'datagram' "
                     "(only 'stream')"]
    assert "baseline" not in {r["impl"] for r in rows}


def test_options_from_the_command_line() -> None:
    p = bench_parser("bench")
    quick = bench_options(p, ["--quick", "--methods", "all", "--no-baseline", "--set", "x=1"])
    assert (quick.nodes, quick.duration, quick.baseline, quick.sets) == (
        (10, 50), 1.0, False, ("x=1",))
    assert quick.methods == ("none", "lockstep", "hlc", "bides")
    assert bench_options(p, ["--out", "a/b.csv"]).out == Path("a/b.csv")
    for bad in (["--nodes", "1,x"], ["--methods", "bides,foo"], ["--events-cap", "0"]):
        with pytest.raises(SystemExit) as exc:
            bench_options(p, bad)
        assert exc.value.code == 2
    assert parse_nodes("200, 1000,") == [200, 1000]
    with pytest.raises(ValueError, match="unknown foo, bar; allowed: none,lockstep,hlc,bides"):
        parse_methods("foo,bides,bar")
    assert parse_methods(" hlc , none ") == ["hlc", "none"]
    assert isinstance(p, argparse.ArgumentParser)


def test_header_lines_and_csv(tmp_path: Path) -> None:
    opts = _opts(duration=3.0, sets=("a=1",))
    assert header_lines(opts, "CPU X")[:2] == [
        "sigma_des engine benchmark: cohort vs events vs baseline  (CPU X)",
        "scenario: defaults + 20 nodes/host, duration 3 s (warm-up 0.6 s); overrides: ['a=1']",
    ]
    assert header_lines(opts, "CPU X")[2].startswith("load average at the start (1, 5, 15 min): ")
    assert header_lines(_opts(), "m")[1].endswith("overrides: none")
    rows, _checks, _notes = run_bench(_opts(), FakeRunner(), lambda _line: None)
    path = tmp_path / "sub" / "bench.csv"
    write_csv(rows, path)
    with path.open() as fh:
        reader = csv.DictReader(fh)
        got = list(reader)
    assert reader.fieldnames == list(COLUMNS)
    assert [(r["impl"], r["scenario"], r["aoi_mean_ms"]) for r in got] == [
        ("cohort", "full", "15.0"), ("events", "full", "15.0"),
        ("cohort", "restricted", "15.0"), ("events", "restricted", "15.0"),
        ("baseline", "restricted", "15.0"),
    ]
