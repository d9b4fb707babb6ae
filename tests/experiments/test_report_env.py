"""experiments/report_env.py turns quick env outputs into docs/ENV.md text."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import bench_env  # noqa: E402
import report_env  # noqa: E402
import train_formation  # noqa: E402


def test_report_from_quick_outputs(tmp_path: Path) -> None:
    assert "no `bench.json`" in report_env.build(tmp_path)  # missing outputs are said
    bench_env.main(["--quick", "--variant", "default", "--out", str(tmp_path)])
    train_formation.main(["--quick", "--out", str(tmp_path / "train")])
    doc = tmp_path / "ENV.md"
    assert report_env.main(["--outputs", str(tmp_path), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert "| 2 scenes × 10 agents |" in text and "Memory per scene" in text
    assert text.count("| untrained | ") == 2 and "| perfect | delay |" in text
    assert "Under delay, the policy trained under delay scores" in text
