"""Smoke run of ``experiments/sweep_nodes.py --quick`` (LocalCluster, 2 workers)."""

from __future__ import annotations

import csv
import importlib.util
import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("matplotlib")

SCRIPT = Path(__file__).resolve().parents[2] / "experiments" / "sweep_nodes.py"
METHODS = ("none", "lockstep", "hlc", "bides")


def _run(out: Path) -> str:
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick", "--no-progress", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_quick_sweep_writes_tables_summary_and_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sn"
    text = _run(out)
    assert "16 runs: 0 already done, 16 run now (16 ok, 0 failed)" in text
    assert "lock-step degrades (AoI > 1.5 × BiDES's): " in text
    for name in ("runs.csv", "aggregate.csv", "summary.json", "sweep.sqlite"):
        assert (out / name).stat().st_size > 0
    for stem in ("aoi_vs_nodes", "latency_vs_nodes", "snapshot_rate_vs_nodes"):
        assert (out / f"{stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    with (out / "runs.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    cols = ["nodes", "hosts", "config_hash", "seed", "method", "metric", "value", "unit"]
    assert list(rows[0]) == cols
    per_run: dict[tuple[str, str, str], dict[str, float]] = defaultdict(dict)
    for r in rows:
        per_run[(r["nodes"], r["seed"], r["method"])][r["metric"]] = float(r["value"])
    assert set(per_run) == {(n, s, m) for n in ("10", "20") for s in ("1", "2") for m in METHODS}
    for key, m in per_run.items():
        # a shown state is at least as old as its delivery took
        assert m["aoi_mean"] >= m["latency_state_mean"] > 0, key

    with (out / "aggregate.csv").open() as fh:
        agg = list(csv.DictReader(fh))
    assert list(agg[0]) == [*cols[:3], "method", "metric", "unit", "n", "mean", "std", "ci95"]
    aoi = [r for r in agg if r["metric"] == "aoi_mean"]
    assert len(aoi) == 8 and {r["n"] for r in aoi} == {"2"}

    summary = json.loads((out / "summary.json").read_text())
    assert summary["nodes"] == [10, 20] and summary["seeds"] == [1, 2]
    assert summary["failed"] == []
    for m in METHODS:
        for n in ("10", "20"):
            fig = summary["figures"][m][n]
            assert fig["aoi_mean"]["mean"] >= fig["latency_state_mean"]["mean"]
    ls = summary["lockstep_degrades_at"]
    expected = "not within the grid" if ls is None else f"N = {ls}"
    assert f"lock-step degrades (AoI > 1.5 × BiDES's): {expected}" in text

    # resumable: a rerun recomputes nothing (in this process: no interpreter start-up)
    spec = importlib.util.spec_from_file_location("sweep_nodes_script", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    before = (out / "runs.csv").read_text()
    assert mod.main(["--quick", "--no-progress", "--out", str(out)]) == 0
    assert "16 runs: 16 already done, 0 run now" in capsys.readouterr().out
    assert (out / "runs.csv").read_text() == before
