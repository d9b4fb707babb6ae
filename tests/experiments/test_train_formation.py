"""experiments/train_formation.py --quick: the learner improves at tiny seeded scale."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import train_formation  # noqa: E402


def test_quick_training_improves_and_writes_outputs(tmp_path: Path) -> None:
    assert train_formation.main(["--quick", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "summary.json").read_text())
    ev = {(r["trained"], r["evaluated"]): r for r in data["eval"]}
    for cond in ("delay", "perfect"):
        # trained in a condition beats the untrained (zero) policy there, on held-out episodes
        assert ev[(cond, cond)]["fitness"] > ev[("untrained", cond)]["fitness"] + 0.05
        curve = [r for r in data["history"] if r["trained"] == cond]
        assert len(curve) == 3
        assert curve[-1]["mean_fitness"] > curve[0]["mean_fitness"] + 0.1
    with (tmp_path / "eval.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 and {"seed", "version", "error", "failed"} <= set(rows[0])
    assert (tmp_path / "learning_curves.png").stat().st_size > 0


def test_training_is_deterministic(tmp_path: Path) -> None:
    from sigma_des.env.learn import CEMConfig, train

    kw = {"scenario": {"nodes": 3}, "max_steps": 8}
    cfg = CEMConfig(population=4, elite=2, iterations=2, episodes=1, seed=3)
    a, ha = train(kw, cfg)
    b, hb = train(kw, cfg)
    assert (a == b).all() and ha == hb
