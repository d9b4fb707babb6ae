"""experiments/report_env.py turns quick env outputs into lab/record/ENV.md text."""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import bench_env  # noqa: E402
import report_env  # noqa: E402
import train_formation  # noqa: E402
from sigma_lab.studies.env_report import build, delay_studies, delay_verdict  # noqa: E402

IMG = ROOT / "lab" / "record" / "img" / "env"


def test_report_from_quick_outputs(tmp_path: Path) -> None:
    assert "no `bench.json`" in build(tmp_path, report_env.TEMPLATES, IMG)  # missing: said
    bench_env.main(["--quick", "--variant", "default", "--out", str(tmp_path)])
    train_formation.main(["--quick", "--out", str(tmp_path / "train")])
    summary = json.loads((tmp_path / "train" / "summary.json").read_text())
    summary["args"]["seed"] = 5
    (tmp_path / "train_seed5").mkdir()
    (tmp_path / "train_seed5" / "summary.json").write_text(json.dumps(summary))
    doc = tmp_path / "ENV.md"
    assert report_env.main(["--outputs", str(tmp_path), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert "| 2 scenes × 10 agents |" in text and "Memory per scene" in text
    assert text.count("| untrained | ") == 2 and "| perfect | delay |" in text
    assert "Under delay, the policy trained under delay scores" in text
    ev = {(r["trained"], r["evaluated"]): r["fitness"] for r in summary["eval"]}
    # the further run's row: its seed, delay condition, budget and 2 x 2 evaluation
    assert f"| `train_seed5` | 5 | 150 ms, 10% | 3 × 6 × 1 × 3 | {ev[('delay', 'delay')]:.3f} |" \
        in text
    assert "of these 1 further runs" in text


def test_delay_study_section_from_a_quick_run(tmp_path: Path) -> None:
    import train_under_delay

    assert "no `delay_*/summary.json`" in delay_studies(tmp_path, report_env.TEMPLATES, IMG)
    train_under_delay.main(["--quick", "--out", str(tmp_path / "delay_quick")])
    text = delay_studies(tmp_path, report_env.TEMPLATES, IMG)
    (r,) = json.loads((tmp_path / "delay_quick" / "summary.json").read_text())["stats"]
    assert "### `delay_quick`: CEM, seeds [0, 1]" in text
    assert (f"| bides@200ms | {r['delay_trained_mean']:.3f} ± {r['delay_trained_ci95']:.3f} | "
            f"{r['perfect_trained_mean']:.3f} ± {r['perfect_trained_ci95']:.3f} | "
            f"{r['diff_mean']:+.3f} ± {r['diff_ci95']:.3f} |") in text
    assert "--learner cem --seeds 2 --max-steps 10 --iterations 2" in text
    assert "Cost: 4 trainings" in text
    assert "Only 2 seed(s) finished" in text  # below the protocol's 5: no conclusion
    rows = [{"cell": "none@50ms", "diff_mean": 0.1, "t_p_greater": 0.01, "wilcoxon_p_greater": 0.03,
             "delay_trained_mean": -0.5, "perfect_trained_mean": -0.6, "naive_fitness": -0.2},
            {"cell": "bides@50ms", "diff_mean": -0.1, "t_p_greater": 0.9, "wilcoxon_p_greater": 0.9,
             "delay_trained_mean": -0.1, "perfect_trained_mean": 0.0, "naive_fitness": -0.2}]
    verdict = delay_verdict(rows, 5)
    assert "in 1 of 2 cells by the mean and in 1 by both paired tests" in verdict
    assert "But in 1 of 2 cells both trained policies score below" in verdict
    assert "gives the better policy under delay in" in verdict and "not shown" not in verdict
