"""The result pages are built from the study folders, facts and files as they are."""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
from sigma_docs_results import MAX_ROWS, results_page  # noqa: E402


def _study(data: Path, name: str, page: str, load: float, scale: str, rows: int,
           kept: int = 0) -> None:
    d = data / name
    d.mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({
        "live_runs_kept": kept, "live_runs_new": 2,
        "name": name, "title": f"Study {name}", "page": page, "about": "What it measures.",
        "date": "2026-01-02T03:04:05Z", "command": f"python experiments/{name}.py",
        "scale": scale, "wall_s": 12.5, "load_before": [load, 1.0, 1.0],
        "load_after": [0.5, 1.0, 1.0], "version": "9.9.9", "commit": "abc1234",
        "machine": {"cpu": "Test CPU", "cores": 4, "memory_gb": 8.0, "system": "Linux",
                    "python": "3.11"}}))
    (d / "table.csv").write_text("n,x\n" + "".join(f"{i},{i * i}\n" for i in range(rows)))
    (d / "stdout.txt").write_text("printed line\n")


def test_a_page_shows_each_study_with_its_facts(tmp_path: Path) -> None:
    _study(tmp_path, "a", "performance", 0.3, "full size", 3)
    _study(tmp_path, "b", "performance", 7.5, "small-scale run (--quick)", MAX_ROWS + 5)
    _study(tmp_path, "c", "validation", 0.1, "full size", 1, kept=30)
    page = results_page("performance", tmp_path)
    # a resumed run's wall time says what it leaves out; a fresh one's says nothing more
    assert ("| Wall time | 12.5 s (resumed: 30 live runs kept from an earlier invocation, "
            "2 new) |") in results_page("validation", tmp_path)
    assert "| Wall time | 12.5 s |" in page
    assert page.index("## Study a") < page.index("## Study b") and "Study c" not in page
    a, b = page.split("## Study b")
    assert "| Date | 2026-01-02T03:04:05Z |" in a and "`python experiments/a.py`" in a
    assert "Test CPU, 4 cores, 8.0 GB" in a and "0.3 / 1.0 / 1.0 before" in a
    assert "| 2 | 4 |" in a and ":::{warning}" not in a and ":::{note}" not in a
    assert "printed line" in a and "{download}`Download table.csv <data/a/table.csv>`" in a
    assert ":::{note}" in b and "up to 7.5 on 4 cores" in b  # small scale, overloaded
    assert f"| {MAX_ROWS - 1} |" in b and f"| {MAX_ROWS} |" not in b
    assert f"First {MAX_ROWS} of {MAX_ROWS + 5} rows" in b


def test_a_page_without_studies_says_so(tmp_path: Path) -> None:
    assert "No study has been filed" in results_page("validation", tmp_path / "none")


def test_the_validation_page_tabulates_every_validation(tmp_path: Path) -> None:
    # two earlier validations' rows and the filed run's held-out rows, counted by hand
    _study(tmp_path, "validation", "validation", 0.1, "full size", 1)
    (tmp_path / "validations-previous.csv").write_text(
        "validation,cell,method,metric,regime,live,des,rel_error\n"
        "T1,a,none,aoi_mean,node-below,10,11,0.1\n"
        "T1,a,none,aoi_p99,node-below,10,12,0.2\n"
        "T1,b,none,aoi_mean,node-below,10,8.4,-0.16\n"
        "T1,a,none,missed_frac,node-below,0.1,0.15,5\n"
        "T2,a,none,aoi_mean,node-below,10,10,0\n"
        "T2,a,none,latency_state_mean,node-below,0,1,nan\n")
    (tmp_path / "validation" / "cells.csv").write_text(
        "cell,held_out,method,metric,rel_error\n"
        "a,True,none,aoi_mean,0.15\n"
        "b,True,none,missed_frac,-12\n"
        "cal-r1,False,none,aoi_mean,0.9\n")
    page = results_page("validation", tmp_path)
    assert "## Every validation, scored by the current model" in page
    assert "| T1 | 1 of 2 (50 %) | 0 of 1 (0 %) | – | 1 of 1 (100 %) |" in page
    assert "| T2 | 1 of 1 (100 %) | – | – | – |" in page  # a NaN error is not scored
    assert "| the filed run (above) | 1 of 1 (100 %) | – | – | 0 of 1 (0 %) |" in page
    assert "<data/validations-previous.csv>" in page
    assert "Every validation" not in results_page("performance", tmp_path)
