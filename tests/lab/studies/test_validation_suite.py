"""The validation suite keeps a calibration only while it was made from the runs there now."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from sigma_lab.studies.validation.suite import calibration_kept, runs_stamp


def _campaign(out: Path, runs: dict[str, str]) -> None:
    for name, text in runs.items():
        (out / "live" / name).mkdir(parents=True)
        (out / "live" / name / "summary.json").write_text(text)
    (out / "cal").mkdir()
    (out / "cal" / "calibrated.json").write_text("{}")


def _source(out: Path, cells: list[str], args: list[str]) -> dict[str, object]:
    return {"cell": cells[0], "cells": cells, "args": args, "runs": runs_stamp(out, cells)}


def test_runs_stamp_is_each_summarys_sha256_prefix(tmp_path: Path) -> None:
    _campaign(tmp_path, {"cal-r1": '{"a": 1}'})
    want = hashlib.sha256(b'{"a": 1}').hexdigest()[:16]
    assert runs_stamp(tmp_path, ["cal-r1", "gone"]) == {"cal-r1": want, "gone": ""}


def test_kept_only_for_the_same_runs_cells_and_options(tmp_path: Path) -> None:
    _campaign(tmp_path, {"cal-r1": '{"run": 1}', "cal-bundle": '{"run": 2}'})
    cells = ["cal-r1", "cal-bundle"]
    made = _source(tmp_path, cells, [])
    (tmp_path / "cal" / "source.json").write_text(json.dumps(made))
    assert calibration_kept(tmp_path, _source(tmp_path, cells, []))
    assert not calibration_kept(tmp_path, _source(tmp_path, cells, ["--one-thread"]))
    assert not calibration_kept(tmp_path, _source(tmp_path, ["cal-r2", "cal-bundle"], []))
    # the calibration run made again (e.g. after it ran under load): stale
    (tmp_path / "live" / "cal-r1" / "summary.json").write_text('{"run": 3}')
    assert not calibration_kept(tmp_path, _source(tmp_path, cells, []))


def test_not_kept_without_fingerprints_or_without_a_report(tmp_path: Path) -> None:
    _campaign(tmp_path, {"cal-r1": "{}"})
    old = {"cell": "cal-r1", "cells": ["cal-r1"], "args": []}  # written before fingerprints
    (tmp_path / "cal" / "source.json").write_text(json.dumps(old))
    assert not calibration_kept(tmp_path, _source(tmp_path, ["cal-r1"], []))
    (tmp_path / "cal" / "source.json").write_text(json.dumps(_source(tmp_path, ["cal-r1"], [])))
    assert calibration_kept(tmp_path, _source(tmp_path, ["cal-r1"], []))
    (tmp_path / "cal" / "calibrated.json").unlink()
    assert not calibration_kept(tmp_path, _source(tmp_path, ["cal-r1"], []))
