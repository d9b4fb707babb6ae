"""Residuals across validations: hand-computed pairs, the earlier validations' table and
the shipped file made from the docs' data."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest
from sigma_lab.studies.validation.cross import (
    COLUMNS,
    add,
    cross_values,
    main,
    read_table,
    shipped_toml,
    validations,
    within_values,
)

from sigma_des.calibrate.intervals import load_residuals

DATA = Path(__file__).resolve().parents[3] / "docs" / "results" / "data"


def _row(cell: str, metric: str, live: float, des: float, regime: str = "node-below",
         held_out: bool = True, passed: object = True, rule: str = "band"
         ) -> dict[str, object]:
    e = 100 * (des - live) if metric == "missed_frac" else (des - live) / live
    return {"cell": cell, "method": "none", "metric": metric, "regime": regime,
            "live": live, "des": des, "rel_error": e, "held_out": held_out,
            "passed": passed, "rule": rule}


def test_cross_values_by_hand() -> None:
    # X: DES 11 against live 10 (+10 %); Y: DES 12 against live 8 (+50 %), another regime
    x = [_row("n30-node", "aoi_mean", 10.0, 11.0),
         _row("n30-node", "missed_frac", 0.0, 0.01)]
    y = [_row("n30-node", "aoi_mean", 8.0, 12.0, regime="node-near"),
         _row("n30-node", "missed_frac", 0.02, 0.01, regime="node-near"),
         _row("n60-node", "aoi_mean", 9.0, 9.0)]  # no partner in X: no cross residual
    c = cross_values({"X": x, "Y": y})
    # X's DES against Y's live: (11 - 8) / 8, in X's regime; Y's against X's: (12 - 10) / 10
    assert c[("aoi_mean", "node-below")] == pytest.approx([0.375])
    assert c[("aoi_mean", "node-near")] == pytest.approx([0.2])
    assert sorted(c[("aoi_mean", "any")]) == pytest.approx([0.2, 0.375])
    # missed frames in points: X 1 % against Y's 2 % live: -1 pp; Y 1 % against 0 %: +1 pp
    assert c[("missed_frac", "node-below")] == pytest.approx([-1.0])
    assert c[("missed_frac", "node-near")] == pytest.approx([1.0])
    w = within_values({"X": x, "Y": y})
    assert sorted(w[("aoi_mean", "any")]) == pytest.approx([0.0, 0.1, 0.5])


def test_shipped_file_joins_within_and_cross(tmp_path: Path) -> None:
    x = [_row("a", "aoi_mean", 10.0, 11.0)]
    y = [_row("a", "aoi_mean", 8.0, 12.0)]
    p = tmp_path / "r.toml"
    p.write_text(shipped_toml({"X": x, "Y": y}, "by hand"))
    table, meta = load_residuals(p)
    assert (meta["validations"], meta["cross_pairs"], meta["source"]) == (2, 2, "by hand")
    r = table[("aoi_mean", "node-below")]  # +10, +50 (own), +37.5, +20 (cross): n = 4
    assert (r.n, r.lo, r.hi, r.enough) == (4, pytest.approx(0.1), pytest.approx(0.5), False)


def test_table_keeps_held_out_rows_with_a_residual_and_refuses_a_tag_twice(
        tmp_path: Path) -> None:
    """Scored held-out rows and the trigger rates live did not hold are kept; the
    calibration's rows and a row with no DES value to score are not."""
    cells = tmp_path / "cells.csv"
    rows = [_row("a", "aoi_mean", 10.0, 11.0),
            _row("cal-r1", "aoi_mean", 10.0, 10.5, held_out=False),
            _row("b", "trigger_rate_hz", 90.0, 81.0, "node-limited", passed="",
                 rule="rate not held"),
            _row("c", "aoi_p99", 20.0, 18.0, passed=False),  # scored: outside the band
            _row("d", "aoi_mean", 10.0, math.nan, passed="", rule="n/a")]
    with cells.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    table = tmp_path / "previous.csv"
    assert main(["add", "2026-12-07T09:13", str(cells), str(table)]) == 0
    got = read_table(table)["2026-12-07T09:13"]
    assert [(r["cell"], r["metric"]) for r in got] == [
        ("a", "aoi_mean"), ("b", "trigger_rate_hz"), ("c", "aoi_p99")]
    assert got[1]["regime"] == "node-limited" and got[1]["rel_error"] == pytest.approx(-0.1)
    assert got[2]["rel_error"] == pytest.approx(-0.1)
    assert list(got[0]) == list(COLUMNS)
    with pytest.raises(ValueError, match="already holds"):
        add(table, "2026-12-07T09:13", cells)
    with pytest.raises(SystemExit) as e:
        main(["add", "2026-12-07T09:13", str(cells), str(table)])
    assert e.value.code == 2
    # the filed validation joins the table's under the name 'filed' ...
    other = tmp_path / "other.csv"
    with other.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows([_row("a", "aoi_mean", 10.5, 11.0), rows[3]])
    both = validations(table, other)
    assert list(both) == ["2026-12-07T09:13", "filed"]
    assert [r["cell"] for r in both["filed"]] == ["a", "c"]
    # ... unless the table holds it already (its residuals would count twice)
    with pytest.raises(ValueError, match="already holds the filed validation"):
        validations(table, cells)


def test_the_shipped_residuals_are_the_docs_validations() -> None:
    """``sigma_des/calibrate/residuals.toml`` is what the filed validation's ``cells.csv``
    and the earlier validations' table make (experiments/make_docs_results.py)."""
    made = shipped_toml(validations(DATA / "validations-previous.csv",
                                    DATA / "validation" / "cells.csv"), "x")
    ours, meta = load_residuals()
    theirs, tmeta = load_residuals_text(made)
    assert meta["validations"] == tmeta["validations"] == len(
        read_table(DATA / "validations-previous.csv")) + 1
    assert set(ours) == set(theirs)
    for key, r in ours.items():
        t = theirs[key]
        assert (r.n, r.enough) == (t.n, t.enough)
        assert math.isclose(r.lo, t.lo, abs_tol=1e-6) and math.isclose(r.hi, t.hi, abs_tol=1e-6)


def load_residuals_text(text: str) -> tuple[dict, dict]:  # type: ignore[type-arg]
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "r.toml"
        p.write_text(text)
        return load_residuals(p)
