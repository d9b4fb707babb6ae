"""studies/run.py and output.py: run_study on the local executor, records, tidy rows."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from conftest import tiny
from sigma_lab.studies import (
    CSV_COLUMNS,
    MethodSpec,
    Study,
    aggregate,
    run_study,
    tidy_rows,
    write_study,
)

SPECS = [
    MethodSpec("none", "none"),
    MethodSpec("lockstep", "lockstep"),
    MethodSpec("lockstep_evict", "lockstep", ("lockstep.eviction_timeout=0.05",)),
]


def _args(jobs: int, out: Path) -> argparse.Namespace:
    return argparse.Namespace(seeds=[1, 2], jobs=jobs, progress=False, quick=True, out=out)


def _study(jobs: int, out: Path) -> Study:
    base = tiny(duration=0.4, warmup=0.1)
    variants = {"a": lambda s: replace(base, seed=s), "b": lambda s: replace(base, seed=s + 10)}
    return run_study("t", _args(jobs, out), variants, {"a": SPECS, "b": SPECS[:1]})


def test_records_labels_and_overrides(tmp_path: Path) -> None:
    st = _study(1, tmp_path)
    assert [(r.variant, r.seed, r.label) for r in st.records] == [
        ("a", 1, "none"), ("a", 1, "lockstep"), ("a", 1, "lockstep_evict"),
        ("a", 2, "none"), ("a", 2, "lockstep"), ("a", 2, "lockstep_evict"),
        ("b", 11, "none"), ("b", 12, "none"),
    ]
    plain, evict = st.runs("a", "lockstep")[0], st.runs("a", "lockstep_evict")[0]
    # labels without overrides share one compare() run; an override label runs its own
    assert plain.results is st.runs("a", "none")[0].results
    assert evict.results is not plain.results
    assert evict.results.scenario.lockstep.eviction_timeout == 0.05
    assert st.variants["a"].seed == 1 and st.variants["b"].seed == 11
    rows = tidy_rows(st)
    assert {r["method"] for r in rows if r["variant"] == "a"} == {"none", "lockstep",
                                                                   "lockstep_evict"}
    assert all(set(CSV_COLUMNS) <= set(r) for r in rows)
    agg = aggregate(st)
    assert agg["a"]["per_seed"]["none"]["aoi_mean"] == [
        r.metrics["aoi_mean"] for r in st.runs("a", "none")
    ]
    assert agg["a"]["overrides"]["lockstep_evict"] == ["lockstep.eviction_timeout=0.05"]


def test_two_jobs_write_the_same_files_as_one(tmp_path: Path) -> None:
    files = {}
    for jobs in (1, 2):
        out = tmp_path / f"j{jobs}"
        write_study(_study(jobs, out))
        summary = json.loads((out / "summary.json").read_text())
        summary.pop("wall")
        files[jobs] = ((out / "results.csv").read_text(), (out / "timeseries.csv").read_text(),
                       summary)
    assert files[1] == files[2]
