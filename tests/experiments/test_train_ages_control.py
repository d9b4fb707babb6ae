"""experiments/train_ages_control.py: retraining reproduces the study; hidden ages are 0."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import train_ages_control  # noqa: E402
import train_under_delay  # noqa: E402


def test_control_reproduces_the_study_and_hides_the_ages(tmp_path: Path) -> None:
    study, ctl = tmp_path / "delay_q", tmp_path / "delay_q_ages_control"
    assert train_under_delay.main(["--quick", "--out", str(study)]) == 0
    assert train_ages_control.main(["--study", str(study), "--out", str(ctl)]) == 0
    data = json.loads((ctl / "summary.json").read_text())
    (row,) = data["table"]
    # the retrained perfect-information policies are the study's own (deterministic)
    assert row["reproduces_study"] is True and row["n_seeds"] == 2
    hidden = [r["fitness"] for r in data["rows"] if r["ages"] == "hidden"]
    assert row["perfect_hidden_mean"] == np.mean(hidden)
    # columns 5, 8, 13 are the tight task's ages: own, leader, nearest neighbour
    assert train_ages_control.AGE_COLUMNS == [5, 8, 13]
    import report_env
    from sigma_lab.studies.env_report import delay_studies

    text = delay_studies(tmp_path, report_env.TEMPLATES, tmp_path / "img")  # control follows
    assert text.index("### `delay_q`") < text.index("--study delay_q`") and (
        f"| {row['perfect_hidden_mean']:.3f} ± {row['perfect_hidden_ci95']:.3f} |" in text)


def test_study_with_ages_control_appends_the_control_to_its_summary(tmp_path: Path) -> None:
    out = tmp_path / "study"
    assert train_under_delay.main(["--quick", "--ages-control", "--out", str(out)]) == 0
    data = json.loads((out / "ages_control.json").read_text())
    (row,) = data["table"]
    assert row["reproduces_study"] is True and row["cell"] == "bides@200ms"
    study = json.loads((out / "summary.json").read_text())
    delay = [e["fitness"] for e in study["eval"] if e["trained"] == "bides@200ms"
             and e["evaluated"] == "bides@200ms"]
    assert row["delay_trained_mean"] == np.mean(delay)
    hidden = np.array([r["fitness"] for r in data["rows"] if r["ages"] == "hidden"])
    assert row["diff_vs_hidden_mean"] == np.mean(np.array(delay) - hidden)
    md = (out / "summary.md").read_text()
    assert md.index("Reading.") < md.index("--ages-control`") < md.index("Control reading")
    assert f"| {row['perfect_hidden_mean']:.3f} ± {row['perfect_hidden_ci95']:.3f} |" in md
    assert (out / "ages_control.csv").read_text().startswith("cell,n_seeds,reproduces_study")


def test_control_refuses_a_folder_without_a_study(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        train_ages_control.main(["--study", str(tmp_path)])
    assert e.value.code == 2 and "--study: no summary.json" in capsys.readouterr().err
