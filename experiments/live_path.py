#!/usr/bin/env python
"""Where the live states' latency goes: the server's receive path, per kept live run.

Reads a validation campaign's kept live runs (``<campaign>/live/<cell>/``) and prints,
per cell and method, the live bundle size (records per state PUBLISH), the server
loop's wake-ups, calls and busy time per wake-up, its run-queue wait per CPU second,
how late it ran its trigger timers, and the state latency by receipt rank within a
frame (:mod:`sigma_lab.studies.validation.livepath`). Nothing is run.

    python experiments/live_path.py out/validation                     # every cell
    python experiments/live_path.py out/validation --cells 'n*-bundle' --out /tmp/p.csv
"""

from __future__ import annotations

import argparse
import fnmatch
import sys
from pathlib import Path

import pandas as pd
from sigma_lab.studies.validation.livepath import PATH_COLUMNS, path_md, path_rows


def main(argv: list[str] | None = None) -> int:
    """Print the table (and write it as CSV with ``--out``)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("campaign", help="a live_vs_des.py output folder (with live/<cell>/)")
    p.add_argument("--cells", default="*", metavar="GLOBS",
                   help="comma-separated globs of cell names (default: all)")
    p.add_argument("--out", default=None, help="also write the rows to this CSV file")
    a = p.parse_args(argv)
    live = Path(a.campaign) / "live"
    if not live.is_dir():
        print(f"live_path: campaign: no folder {live}", file=sys.stderr)
        return 2
    globs = a.cells.split(",")
    cells = sorted(c.name for c in live.iterdir()
                   if (c / "cpu.csv").is_file() and any(fnmatch.fnmatch(c.name, g) for g in globs))
    if not cells:
        print(f"live_path: --cells: no kept run matches {a.cells!r}", file=sys.stderr)
        return 2
    rows = [r for c in cells for r in path_rows(live / c, c)]
    print("\n".join(path_md(rows)))
    if a.out:
        pd.DataFrame(rows, columns=list(PATH_COLUMNS)).to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
