"""Regenerate lab/record/ENV.md from the env study outputs (bench_env.py, train_formation.py,
train_under_delay.py).

Usage: ``python experiments/report_env.py --outputs /work/out/env [--doc lab/record/ENV.md]``
(reads ``bench.json``, ``train/summary.json`` and every ``delay_*/summary.json`` under
``--outputs``; a missing one leaves its section saying so).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sigma_lab.studies.env_report import build
from sigma_lab.studies.report import Templates

ROOT = Path(__file__).resolve().parents[1]

#: The document's fixed prose (``experiments/templates/env_*.md``, no fields).
TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")


def main(argv: list[str] | None = None) -> int:
    """Write lab/record/ENV.md (or ``--doc``) from ``--outputs``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", default="/work/out/env")
    ap.add_argument("--doc", default=str(ROOT / "lab" / "record" / "ENV.md"))
    args = ap.parse_args(argv)
    img = ROOT / "lab" / "record" / "img" / "env"
    Path(args.doc).write_text(build(Path(args.outputs), TEMPLATES, img))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

