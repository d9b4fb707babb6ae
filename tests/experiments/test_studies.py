"""The paper-study scripts in ``experiments/``: every ``--quick`` run and its outputs.

Each script runs once (as a subprocess, all in parallel) into a temporary directory;
the tests check that the outputs exist with the required columns and that
inequalities that hold by construction hold:

* Lock-Step and BiDES show one frame for the whole swarm (frame spread 0) whenever
  no node was excluded (``extrapolated_frac == 0``);
* mean AoI >= mean state latency (a shown state was generated before it arrived);
* the per-link wire throughput rows sum to ``throughput_mbps``.

Finally ``make_report.py`` must turn the outputs into a report. Timings of
``alignment_cost`` are never asserted.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXP = ROOT / "experiments"
SIM_STUDIES = ("scale_200", "scale_1000", "latency_tolerance", "faults")
STUDIES = (*SIM_STUDIES, "alignment_cost")
PLOTS = {
    "scale_200": ("metrics.png", "aoi_distribution.png", "aoi_over_time.png"),
    "scale_1000": ("metrics.png", "trigger_rate.png", "aoi_over_time.png"),
    "latency_tolerance": (
        "aoi_over_time.png",
        "aoi_distribution.png",
        "flicker.png",
        "frame_rate.png",
    ),
    "alignment_cost": ("cost_vs_n.png",),
    "faults": ("faults_timeseries.png", "faults_windows.png"),
}
COLUMNS = {
    "study",
    "variant",
    "seed",
    "config_hash",
    "version",
    "method",
    "metric",
    "value",
    "unit",
}
TIMEOUT = 240


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Run every study's ``--quick`` mode (in parallel) into one outputs directory."""
    out = tmp_path_factory.mktemp("studies")
    procs = {
        name: subprocess.Popen(
            [sys.executable, str(EXP / f"{name}.py"), "--quick", "--out", str(out / name)],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for name in STUDIES
    }
    failed = []
    for name, p in procs.items():
        so, se = p.communicate(timeout=TIMEOUT)
        if p.returncode != 0:
            failed.append(f"{name} exited {p.returncode}:\n{so[-2000:]}\n{se[-4000:]}")
    assert not failed, "\n\n".join(failed)
    return out


def read_rows(path: Path) -> list[dict[str, str]]:
    """Rows of a CSV file."""
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def by_run(rows: list[dict[str, str]]) -> dict[tuple[str, str, str], dict[str, float]]:
    """``{(variant, seed, method): {metric: value}}`` from tidy rows."""
    out: dict[tuple[str, str, str], dict[str, float]] = defaultdict(dict)
    for r in rows:
        v = r["value"]
        out[(r["variant"], r["seed"], r["method"])][r["metric"]] = float(v) if v else math.nan
    return out


@pytest.mark.parametrize("name", STUDIES)
def test_outputs_exist_with_required_columns(outputs: Path, name: str) -> None:
    d = outputs / name
    for f in ("summary.json", "results.csv", *PLOTS[name]):
        assert (d / f).is_file() and (d / f).stat().st_size > 0, f"{name}: missing {f}"
    rows = read_rows(d / "results.csv")
    assert rows, f"{name}: empty results.csv"
    assert COLUMNS <= set(rows[0]), f"{name}: columns {sorted(rows[0])}"
    assert all(r["config_hash"] and r["version"] and r["seed"] for r in rows)
    summary: dict[str, Any] = json.loads((d / "summary.json").read_text())
    assert summary["quick"] is True
    assert "--quick" in summary["command"] and name in summary["command"]
    assert set(PLOTS[name]) <= set(summary["plots"])
    if name in SIM_STUDIES:
        ts = read_rows(d / "timeseries.csv")
        assert ts and {"t", "aoi_mean", "f_trig", "aligned_frame"} <= set(ts[0])
        runs = by_run(rows)
        for key, m in runs.items():
            for metric in ("aoi_mean", "aoi_std", "latency_state_mean", "throughput_mbps"):
                assert metric in m, f"{name} {key}: no {metric}"
        # one row per seed × method × metric
        seen = [(r["variant"], r["seed"], r["method"], r["metric"]) for r in rows]
        assert len(seen) == len(set(seen)), f"{name}: duplicate rows"


@pytest.mark.parametrize("name", SIM_STUDIES)
def test_spread_zero_without_exclusions(outputs: Path, name: str) -> None:
    runs = by_run(read_rows(outputs / name / "results.csv"))
    checked = 0
    for (variant, seed, method), m in runs.items():
        if method in ("lockstep", "lockstep_evict", "bides") and m["extrapolated_frac"] == 0:
            assert m["spread_max"] == 0, f"{name} {variant} seed {seed} {method}: {m['spread_max']}"
            checked += 1
    if name in ("scale_200", "scale_1000"):
        assert checked >= 2  # lossless LAN: nobody is ever excluded


@pytest.mark.parametrize("name", SIM_STUDIES)
def test_aoi_at_least_state_latency(outputs: Path, name: str) -> None:
    runs = by_run(read_rows(outputs / name / "results.csv"))
    for key, m in runs.items():
        if math.isfinite(m["aoi_mean"]) and math.isfinite(m["latency_state_mean"]):
            assert m["aoi_mean"] >= m["latency_state_mean"], (name, key, m["aoi_mean"])


@pytest.mark.parametrize("name", SIM_STUDIES)
def test_link_throughput_sums_to_total(outputs: Path, name: str) -> None:
    runs = by_run(read_rows(outputs / name / "results.csv"))
    for key, m in runs.items():
        links = [v for k, v in m.items() if k.startswith("link_mbps.")]
        assert links, f"{name} {key}: no per-link rows"
        assert sum(links) == pytest.approx(m["throughput_mbps"], rel=1e-9, abs=1e-12)
        assert m["throughput_mbps"] > 0


def test_alignment_cost_covers_every_n_and_method(outputs: Path) -> None:
    runs = by_run(read_rows(outputs / "alignment_cost" / "results.csv"))
    variants = {k[0] for k in runs}
    assert {"n=100", "n=300", "n=1000"} <= variants
    for n in variants:
        for method in ("bides", "hlc", "lockstep"):
            m = runs[(n, "1", method)]
            for metric in ("align_median_ms", "align_p95_ms", "ingest_median_ms"):
                assert math.isfinite(m[metric]) and m[metric] >= 0
            assert m["align_p95_ms"] >= m["align_median_ms"]


def test_report_from_quick_outputs(outputs: Path, tmp_path: Path) -> None:
    report = tmp_path / "REPRODUCTION.md"
    cmd = [sys.executable, str(EXP / "make_report.py"), "--outputs", str(outputs)]
    subprocess.run([*cmd, "--report", str(report)], cwd=ROOT, check=True, capture_output=True)
    text = report.read_text()
    for name in STUDIES:
        assert f"(`{name}`)" in text
        assert f"experiments/{name}.py --quick" in text
    assert "could not read" not in text
    assert "Not run yet" not in text
    assert "sweep_nodes" in text  # listed even though absent
    assert "| bides |" in text


def test_report_without_outputs(tmp_path: Path) -> None:
    report = tmp_path / "R.md"
    cmd = [sys.executable, str(EXP / "make_report.py"), "--outputs", str(tmp_path / "none")]
    subprocess.run([*cmd, "--report", str(report)], cwd=ROOT, check=True, capture_output=True)
    assert report.read_text().count("Not run yet") == len(STUDIES)


def test_seed_lists() -> None:
    from sigma_lab import studies as common

    assert common.parse_seeds("1,2,3") == [1, 2, 3]
    assert common.parse_seeds("1-3,7,2") == [1, 2, 3, 7]
    with pytest.raises(Exception, match="bad seed list"):
        common.parse_seeds("a,b")
