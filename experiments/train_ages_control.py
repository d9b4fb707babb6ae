"""Control for the delay study: perfect-trained policies under delay with the ages hidden.

A policy trained with perfect information only ever sees ages of 0; under delay its
age columns carry values it never saw. This script takes the study's
perfect-information policies again (its checkpoints, or retrained: training is
deterministic) and evaluates each under every delay cell with the ages shown (must
equal the study's own figures) and with the age columns set to 0, then compares both
with the delay-trained policies (``sigma_lab.studies.ages_control``).
``train_under_delay.py --ages-control`` runs the same after the study.

Outputs (``--out``): ``control.csv`` and ``summary.json``.

Usage: ``python experiments/train_ages_control.py --study out/env/delay_study
[--out out/env/delay_study_ages_control]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sigma_lab.studies.ages_control import AGE_COLUMNS, run_control

__all__ = ["AGE_COLUMNS", "main"]


def main(argv: list[str] | None = None) -> int:
    """Evaluate shown and hidden, write the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True, help="a train_under_delay.py output directory")
    ap.add_argument("--out", default=None, help="default: <study>_ages_control")
    args = ap.parse_args(argv)
    study = Path(args.study)
    if not (study / "summary.json").exists():
        ap.error(f"--study: no summary.json in {study}")
    out = Path(args.out or f"{args.study.rstrip('/')}_ages_control")
    out.mkdir(parents=True, exist_ok=True)
    run_control(study, out / "control.csv", out / "summary.json",
                log=lambda s: print(s, flush=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
