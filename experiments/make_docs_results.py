#!/usr/bin/env python
"""Run the validation suite and the benchmarks, and file their outputs for the docs.

Each study runs its own script (``experiments/live_vs_des.py``, ``fixed_wing_fit.py``,
``bench_engine.py``, ``bench_env.py``, ``bench_sequence.py``) into a fresh folder; its
output files, the text it printed (``stdout.txt``) and a ``run.json`` (date, machine, load average
before and after, command, scale, wall time, version, git commit) are then copied to
``docs/results/data/<name>/``, replacing what was there. The documentation build
turns those folders into ``docs/results/validation.md`` and ``performance.md``
(``docs/_ext/sigma_docs_results.py``): commit the folders, never the pages.

    python experiments/make_docs_results.py                  # every study, full size
    python experiments/make_docs_results.py --quick          # small-scale runs (labelled)
    python experiments/make_docs_results.py --only engine,env
    python experiments/make_docs_results.py --list
    python experiments/make_docs_results.py --only validation --work runs/  # keep outputs

Nothing is made up: a study that fails leaves its folder as it was and the command
exits 1.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from sigma_lab.studies.machine import machine

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "results" / "data"
#: the earlier validations' scored rows (sigma_lab.studies.validation.cross), joined
#: with the filed one's into the shipped residuals
PREVIOUS = DATA / "validations-previous.csv"
SHIPPED = ROOT / "sigma_des" / "calibrate" / "residuals.toml"
#: how the validations in the shipped residuals were made
SOURCE = "python experiments/live_vs_des.py --calibrate-bundled --out OUT/validation"
#: the kinds of output file filed for the docs
KEEP = (".csv", ".json", ".md", ".png", ".toml", ".txt")


@dataclass(frozen=True)
class Study:
    """One script whose outputs go to ``docs/results/data/<name>/``.

    Attributes:
        name: the folder name.
        title: the section title on the page.
        page: ``validation`` or ``performance``.
        script: the script under ``experiments/``.
        full: its arguments for a full-size run (``{out}`` is the output folder).
        quick: its arguments for a small-scale run.
        about: one paragraph: what the study measures.
    """

    name: str
    title: str
    page: str
    script: str
    full: tuple[str, ...]
    quick: tuple[str, ...]
    about: str


STUDIES = (
    Study("validation", "Live against the DES", "validation", "live_vs_des.py",
          ("--calibrate-bundled", "--loaded-check", "--out", "{out}"),
          ("--quick", "--out", "{out}"),
          "The DES is calibrated on a campaign of live runs, one per node and two "
          "bundled (`sigma-des calibrate RUN RUN RUN`), then predicts "
          "held-out live runs at other sizes, message modes and impairments; each "
          "prediction is scored against the live runs' own spread (the noise floor). "
          "A calibration made beside a CPU hog is scored against an idle one."),
    Study("fixed_wing", "Fixed-wing model fidelity against JSBSim's minisgs", "validation",
          "fixed_wing_fit.py", ("--out", "{out}"), ("--quick", "--out", "{out}"),
          "Our 6-DoF fixed wing tuned by `sigma-des tune` (GA + DTW) to a log flown by "
          "JSBSim's minisgs sailplane, scored on held-out logs (other inputs; another trim "
          "speed): RMS and R² of pitch and roll rate and angle, the paper's Fig. 15 in kind. "
          "The reference is a JSBSim model, not a flight."),
    Study("engine", "Engine speed", "performance", "bench_engine.py",
          ("--out", "{out}/engine.csv"), ("--quick", "--out", "{out}/engine.csv"),
          "Wall time, events per second and peak memory of the compiled `cohort` engine, "
          "the per-message `events` engine and a process-per-message SimPy baseline, each "
          "case in a fresh process; the two engines' metrics must be bit-identical."),
    Study("env", "Learning environment speed", "performance", "bench_env.py",
          ("--out", "{out}"), ("--quick", "--out", "{out}"),
          "CPU time per agent-step of the PettingZoo environment for 1 to 500 scenes and "
          "each alignment method, and memory per scene."),
    Study("env_study", "Learning environment speed: the delay study's configuration",
          "performance", "bench_env.py", ("--study", "--out", "{out}"),
          ("--study", "--quick", "--out", "{out}"),
          "Agent-steps per CPU-second of `SwarmVec` on the training-under-delay study's "
          "configuration (tight task, 4 agents a scene, BiDES at 200 ms with 10 % loss, and "
          "perfect information) at 4 and 64 scenes, against the targets (20 000 and "
          "50 000): the headline is the steady state of the study's training episodes "
          "(at most 50 steps, random actions, so the episodes' restarts are in it at their "
          "real rate), and beside it the best batch within episodes (restarts excluded). "
          "Then the resident memory 512 scenes take, the SimPy baseline's CPU per "
          "simulated second in the same run (divide by it to compare machines), and one "
          "PPO training with the study's settings timed (wall and CPU, one core), "
          "projected to the study's 2 x 10^6 agent-steps per policy (target: 15 minutes)."),
    Study("delay", "Training under delay (PPO)", "learning", "train_under_delay.py",
          ("--full", "--jobs", "2", "--ages-control", "--out", "{out}", "--checkpoints",
           "{out}/checkpoints"),
          ("--quick", "--ages-control", "--out", "{out}"),
          "Does a policy trained on the aligned, delayed view beat one trained with perfect "
          "information, under delay? PPO (Stable-Baselines3) at 2 x 10^6 agent-steps per "
          "policy, 5 seeds per condition (perfect information; BiDES and none at 50 and "
          "200 ms with 10 % loss), every policy and the hand-written controllers scored on "
          "the same held-out episodes, paired tests over seeds; then the ages-hidden "
          "control (the perfect-trained policies with their age inputs set to 0). "
          "Resumable: rerun with the same `--work` folder to go on."),
    Study("delay_lstm", "Training under delay (recurrent PPO)", "learning",
          "train_under_delay.py",
          ("--full", "--policy", "lstm", "--delays", "0.2", "--jobs", "2", "--ages-control",
           "--out", "{out}", "--checkpoints", "{out}/checkpoints"),
          ("--learner", "ppo", "--policy", "lstm", "--seeds", "2", "--delays", "0.2",
           "--methods", "bides", "--nodes", "3", "--max-steps", "10", "--eval-episodes", "2",
           "--ppo-steps", "32", "--ppo-scenes", "2", "--ppo-n-steps", "8", "--ppo-batch", "16",
           "--ages-control", "--out", "{out}"),
          "The same question with recurrent policies (sb3-contrib RecurrentPPO, an LSTM of "
          "64 units), which can carry what they saw across decisions: 2 x 10^6 agent-steps "
          "per policy, 5 seeds per condition (perfect information; BiDES and none at 200 ms "
          "with 10 % loss), the same held-out episodes, paired tests and ages-hidden "
          "control."),
    Study("sequence", "Cost per run in a sequence", "performance", "bench_sequence.py",
          (), ("--quick",),
          "Many short runs in one process (as a sweep runs them): CPU seconds, page faults "
          "and peak memory per run."),
)


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def _git(*args: str) -> str:
    r = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else ""


def run_study(s: Study, quick: bool, work: Path | None = None) -> bool:
    """Run one study and file its outputs; False (folder untouched) if it failed.

    With ``work`` the study writes to ``work/<name>`` and the folder is kept: a
    resumable script (the validation suite) resumes there, and its per-run folders
    stay for later rescoring. Otherwise a temporary folder is used.
    """
    from sigma_des.version import __version__

    with tempfile.TemporaryDirectory(prefix=f"docs_{s.name}_") as tmp:
        out = (work / s.name) if work is not None else Path(tmp) / "out"
        out.mkdir(parents=True, exist_ok=True)
        args = [a.format(out=out) for a in (s.quick if quick else s.full)]
        shown = ["python", f"experiments/{s.script}",
                 *[a.replace(str(out), f"OUT/{s.name}") for a in args]]
        print(f"== {s.name}: {shlex.join(shown)}", flush=True)
        kept = _live_runs(out)  # a resumed suite keeps these: its wall time is not theirs
        load0, t0 = _load(), time.monotonic()
        started = dt.datetime.now(dt.UTC).replace(microsecond=0)
        r = subprocess.run([sys.executable, str(ROOT / "experiments" / s.script), *args],
                           cwd=ROOT, capture_output=True, text=True)
        wall, load1 = time.monotonic() - t0, _load()
        sys.stdout.write(r.stdout[-2000:])
        if r.returncode not in (0,):
            print(f"{s.name}: exit {r.returncode}; its folder is left as it was\n"
                  f"{r.stderr[-2000:]}", file=sys.stderr)
            return False
        dest = DATA / s.name
        shutil.rmtree(dest, ignore_errors=True)
        dest.mkdir(parents=True)
        for f in sorted(out.iterdir()):  # the study's tables, summary and plots; the
            if f.is_file() and f.suffix in KEEP:  # per-run folders stay out of git
                shutil.copy2(f, dest / f.name)
        (dest / "stdout.txt").write_text(r.stdout)
        for f in dest.iterdir():  # no path of this machine in what is committed
            if f.suffix != ".png":
                f.write_text(f.read_text().replace(str(out), f"OUT/{s.name}")
                             .replace(str(ROOT), "."))
        run = {"name": s.name, "title": s.title, "page": s.page, "about": s.about,
               "date": started.isoformat().replace("+00:00", "Z"),
               "command": shlex.join(shown),
               "scale": "small-scale run (--quick)" if quick else "full size",
               "wall_s": round(wall, 1), "load_before": load0, "load_after": load1,
               "live_runs_kept": kept, "live_runs_new": _live_runs(out) - kept,
               "machine": machine(), "version": __version__,
               "commit": _git("rev-parse", "--short", "HEAD")}
        (dest / "run.json").write_text(json.dumps(run, indent=2) + "\n")
        print(f"filed {dest.relative_to(ROOT)} ({wall:.0f} s)")
        if s.name == "validation" and not quick:
            _ship_residuals(dest / "cells.csv")
        return True


def _live_runs(out: Path) -> int:
    """Live runs finished in a study's output folder (``live/*/summary.json``, and the
    validation's loaded run, ``loaded/*/*/summary.json``)."""
    return len([*out.glob("live/*/summary.json"), *out.glob("loaded/*/*/summary.json")])


def _ship_residuals(filed: Path) -> None:
    """``predict``'s residuals from the filed validation's ``cells.csv`` and the earlier
    validations' rows (:data:`PREVIOUS`), each against its own live runs and against
    the others' (:func:`sigma_lab.studies.validation.cross.shipped_toml`). Before filing
    a validation on new live runs, add the one it replaces to :data:`PREVIOUS`
    (``python -m sigma_lab.studies.validation.cross add``); every validation there must
    be scored by the model being filed: after a change to the model, rerun
    ``experiments/live_vs_des.py`` on a copy of its ``live/`` and ``cells/*.live.json``."""
    from sigma_lab.studies.validation.cross import shipped_toml, validations

    SHIPPED.write_text(shipped_toml(validations(PREVIOUS, filed), SOURCE))
    print(f"wrote {SHIPPED.relative_to(ROOT)}")


def main(argv: list[str] | None = None) -> int:
    """Run the chosen studies; 1 if any failed."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true",
                   help="small-scale runs (each script's --quick), labelled as such")
    p.add_argument("--only", default="", help="comma-separated study names")
    p.add_argument("--list", action="store_true", help="list the studies and exit")
    p.add_argument("--work", type=Path, default=None, metavar="DIR",
                   help="keep each study's output folder under DIR (resumable scripts "
                        "resume there); default: a temporary folder")
    args = p.parse_args(argv)
    if args.list:
        for s in STUDIES:
            print(f"{s.name:12} {s.page:12} experiments/{s.script}")
        return 0
    names = [n for n in args.only.split(",") if n] or [s.name for s in STUDIES]
    unknown = sorted(set(names) - {s.name for s in STUDIES})
    if unknown:
        p.error(f"--only: unknown {unknown}; allowed: {', '.join(s.name for s in STUDIES)}")
    ok = [run_study(s, args.quick, args.work) for s in STUDIES if s.name in names]
    return 0 if all(ok) else 1


if __name__ == "__main__":
    raise SystemExit(main())
