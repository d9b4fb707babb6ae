"""experiments/train_under_delay.py: quick CEM run (no SB3 needed), the statistics, bad input."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import train_under_delay  # noqa: E402


def test_quick_study_writes_consistent_outputs(tmp_path: Path) -> None:
    assert train_under_delay.main(["--quick", "--out", str(tmp_path)]) == 0
    with (tmp_path / "eval.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    fit = {(r["trained"], int(r["seed"]), r["evaluated"]): float(r["fitness"]) for r in rows}
    cells = ["perfect", "bides@200ms"]
    for name in ("untrained", "naive", "extrapolating"):  # baselines everywhere, once
        assert all((name, -1, c) in fit for c in cells)
    for seed in (0, 1):  # perfect-trained: every cell; delay-trained: perfect and its own
        assert all(("perfect", seed, c) in fit for c in cells)
        assert ("bides@200ms", seed, "bides@200ms") in fit
    assert len(rows) == 3 * 2 + 2 * 2 + 2 * 2
    data = json.loads((tmp_path / "summary.json").read_text())
    (row,) = data["stats"]
    d = np.array([fit[("bides@200ms", s, "bides@200ms")] for s in (0, 1)])
    p = np.array([fit[("perfect", s, "bides@200ms")] for s in (0, 1)])
    assert row["cell"] == "bides@200ms" and row["n_seeds"] == 2
    assert row["diff_mean"] == pytest.approx((d - p).mean(), rel=1e-12)
    # 95 % CI half-width of two values: t(0.975, 1) * sd / sqrt(2) = 12.706 * |a - b| / 2
    assert row["delay_trained_ci95"] == pytest.approx(12.7062047 * abs(d[0] - d[1]) / 2,
                                                      rel=1e-6)
    assert row["naive_fitness"] == fit[("naive", -1, "bides@200ms")]
    # the hand-written controller holds the slot far better than the zero policy
    assert row["naive_fitness"] > row["untrained_fitness"] + 1.0
    curve = [r for r in data["cost"] if r["trained"] == "perfect"]
    assert len(curve) == 2 and all(r["agent_steps"] == 2 * 4 * 1 * 10 * 2 for r in curve)
    for png in ("learning_curves.png", "eval.png"):
        assert (tmp_path / png).stat().st_size > 0
    # the page's text: each seed under perfect information against the better controller
    pp = [fit[("perfect", s, "perfect")] for s in (0, 1)]
    best = max(fit[("naive", -1, "perfect")], fit[("extrapolating", -1, "perfect")])
    md = (tmp_path / "summary.md").read_text()
    assert (f"per seed {pp[0]:.3f}, {pp[1]:.3f}: {sum(x >= best for x in pp)} of 2 at or "
            "above the better hand-written controller") in md
    walls = sorted(c["train_wall_s"] for c in data["cost"])
    assert f"per policy median {walls[2]:.0f} s, {walls[0]:.0f}–{walls[-1]:.0f} s" in md


@pytest.mark.parametrize(("args", "msg"), [(["--seeds", "0"], "--seeds: must be >= 1"),
                                           (["--loss", "1.5"], "--loss: must be in")])
def test_bad_arguments_exit_2_naming_the_option(args: list[str], msg: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        train_under_delay.main(args)
    assert exc.value.code == 2 and msg in capsys.readouterr().err


def test_shards_merge_to_the_same_study(tmp_path: Path) -> None:
    full, a, b, m = (tmp_path / x for x in ("full", "a", "b", "merged"))
    assert train_under_delay.main(["--quick", "--out", str(full)]) == 0
    assert train_under_delay.main(["--quick", "--seed-list", "1", "--out", str(a)]) == 0
    assert train_under_delay.main(["--quick", "--seed-list", "0", "--skip-baselines",
                                   "--out", str(b)]) == 0
    assert train_under_delay.main(["--quick", "--merge", str(a), str(b), "--out", str(m)]) == 0
    want = json.loads((full / "summary.json").read_text())
    got = json.loads((m / "summary.json").read_text())
    assert got["seeds_done"] == [0, 1] and got["stats"] == want["stats"]
    with (m / "history.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2 * 2 and rows[0]["learner"] == "cem"  # seeds x cells x iterations
    with pytest.raises(SystemExit, match="share a seed"):
        train_under_delay.main(["--merge", str(a), str(full), "--out", str(m)])


def test_train_only_perfect_evaluates_it_everywhere(tmp_path: Path) -> None:
    assert train_under_delay.main(["--quick", "--train", "perfect", "--out",
                                   str(tmp_path)]) == 0
    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["stats"] == []  # no delay-trained policy: no paired cell
    assert {e["trained"] for e in data["eval"]} == {"untrained", "naive", "extrapolating",
                                                    "perfect"}
    assert len(data["eval"]) == 3 * 2 + 2 * 2
    under = data["evaluated_under"]["bides@200ms"]
    fit = [e["fitness"] for e in data["eval"]
           if e["trained"] == "perfect" and e["evaluated"] == "bides@200ms"]
    (row,) = [r for r in under if r["policy"] == "trained perfect"]
    assert row["n"] == 2 and row["mean"] == pytest.approx(np.mean(fit), rel=1e-12)


def test_train_names_an_unknown_condition(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        train_under_delay.main(["--quick", "--train", "hlc@5ms"])
    assert exc.value.code == 2 and "--train: unknown condition 'hlc@5ms'" in (
        capsys.readouterr().err)


def test_jobs_train_the_seeds_in_processes_and_merge_to_the_same_study(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    assert train_under_delay.main(["--quick", "--out", str(one)]) == 0
    assert train_under_delay.main(["--quick", "--jobs", "2", "--out", str(two)]) == 0
    want = json.loads((one / "summary.json").read_text())
    got = json.loads((two / "summary.json").read_text())
    assert got["seeds_done"] == [0, 1] and got["stats"] == want["stats"]
    # shard k trained seeds[k::2]; only shard 0 evaluated the baselines
    for k, seed in enumerate((0, 1)):
        part = json.loads((two / "shards" / str(k) / "summary.json").read_text())
        assert part["seeds_done"] == [seed]
        assert any(e["seed"] == -1 for e in part["eval"]) == (k == 0)
    # a rerun resumes from the shared checkpoint folder: nothing is trained again
    capsys.readouterr()
    assert train_under_delay.main(["--quick", "--jobs", "2", "--out", str(two)]) == 0
    printed = capsys.readouterr().out
    assert printed.count("done before") == 4 and " trained (" not in printed
    assert "[shard 0] seed 0 perfect" in printed and "[shard 1] seed 1 perfect" in printed
    assert json.loads((two / "summary.json").read_text())["stats"] == want["stats"]
    assert "resumed: this run took" in (two / "summary.md").read_text()  # not "N s in all"


def test_shard_command_lines_replace_the_parents_own_options() -> None:
    from sigma_lab.studies.delay_jobs import shard_argv

    argv = ["--full", "--jobs", "2", "--out=x", "--seeds", "5", "--policy", "lstm",
            "--ages-control"]  # the parent runs the control once, after the merge
    got = shard_argv(argv, 1, [1, 3], Path("o/1"), "ck")
    assert got == ["--full", "--policy", "lstm", "--seed-list", "1,3", "--out", "o/1",
                   "--checkpoints", "ck", "--skip-baselines"]


def test_full_keeps_a_given_part_of_the_study() -> None:
    part = train_under_delay._parse(["--full", "--policy", "lstm", "--delays", "0.2"])
    assert (part.delay_list, part.method_list, part.policy) == ([0.2], ["bides", "none"], "lstm")
    assert (part.ppo_steps, part.seeds, part.out) == (2_000_000, 5, "out/env/delay_ppo_lstm")
    whole = train_under_delay._parse(["--full"])
    assert whole.delay_list == [0.05, 0.2] and whole.method_list == ["bides", "none"]
