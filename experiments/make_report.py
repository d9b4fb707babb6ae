#!/usr/bin/env python
"""Regenerate ``lab/record/REPRODUCTION.md`` from the studies' outputs.

Reads ``summary.json`` of every study under the outputs directory (default
``out/``): ``scale_200``, ``scale_1000``, ``latency_tolerance``, ``alignment_cost``,
``faults`` and, if present, ``sweep_nodes``; for each it writes the paper's figure,
ours (tables), the command that produced ours, and why they differ. A study
whose outputs are missing is listed with the command that would produce them.

Examples::

    python experiments/make_report.py                          # out/ -> lab/record/REPRODUCTION.md
    python experiments/make_report.py --outputs /tmp/q --report /tmp/q/REPORT.md
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from report_cost import sec_cost
from report_faults import sec_faults
from report_latency import sec_latency
from report_scale import sec_scale_200, sec_scale_1000
from report_sweep import sec_sweep
from sigma_lab.studies.report import Templates, plots_line, provenance

ROOT = Path(__file__).resolve().parent.parent
#: The sections' prose, one ``str.format`` template per section (``experiments/templates``).
TEMPLATES = Templates(Path(__file__).resolve().parent / "templates")
STUDIES = ("scale_200", "scale_1000", "latency_tolerance", "alignment_cost", "faults")


SECTIONS: dict[str, tuple[str, Callable[[dict[str, Any]], str]]] = {
    "scale_200": ("200 nodes: latency, AoI, memory, throughput, frame rate", sec_scale_200),
    "scale_1000": ("1000 nodes: throughput, AoI, adaptive trigger rate", sec_scale_1000),
    "latency_tolerance": ("Latency tolerance: 30 % loss, 30 ± 10 ms delay", sec_latency),
    "alignment_cost": ("Cost of the alignment step (Algorithm 1)", sec_cost),
    "faults": ("Faults: crash, straggler, degraded host", sec_faults),
    "sweep_nodes": ("Node-count sweep", sec_sweep),
}


def build(outputs: Path) -> str:
    """The whole report as Markdown."""
    head = TEMPLATES.fill("head", out=outputs.name)
    body = [head]
    for i, (name, (title, fn)) in enumerate(SECTIONS.items(), start=1):
        path = outputs / name / "summary.json"
        body.append(f"## {i}. {title} (`{name}`)\n")
        if not path.exists():
            if name == "sweep_nodes":
                body.append(
                    "Not run: `python experiments/sweep_nodes.py` writes "
                    f"`{outputs.name}/sweep_nodes/summary.json`.\n"
                )
            else:
                body.append(f"Not run yet: `python experiments/{name}.py`.\n")
            continue
        s = json.loads(path.read_text())
        try:
            text = fn(s)
        except (KeyError, TypeError, ValueError, StopIteration, AssertionError) as e:
            text = f"(could not read `{path}`: {type(e).__name__}: {e})"
        body.append(text + "\n")
        if name != "sweep_nodes":
            body.append(provenance(s) + " " + plots_line(name, s, outputs) + "\n")
        else:
            pngs = {"plots": sorted(p.name for p in path.parent.glob("*.png"))}
            body.append(
                "Command: `python experiments/sweep_nodes.py` (see [`SWEEPS.md`](SWEEPS.md)). "
                + plots_line(name, pngs, outputs)
                + "\n"
            )
    from report_interpolation import section as interpolation_section  # issue 12

    body.append(interpolation_section(outputs))
    from report_model_tuning import section as model_tuning_section

    body.append(model_tuning_section(outputs))
    from report_peer import section as peer_section

    body.append(peer_section(outputs))
    return "\n".join(body).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the report."""
    p = argparse.ArgumentParser(
        prog="experiments/make_report.py",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--outputs", type=Path, default=Path("out"), help="studies' output directory")
    p.add_argument(
        "--report", type=Path, default=ROOT / "lab" / "record" / "REPRODUCTION.md",
        help="report to write",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 if the report would differ from --report",
    )
    a = p.parse_args(argv)
    text = build(a.outputs)
    if a.check:
        same = a.report.exists() and a.report.read_text() == text
        print(f"{a.report} is {'up to date' if same else 'OUT OF DATE'} for {a.outputs}")
        return 0 if same else 1
    a.report.parent.mkdir(parents=True, exist_ok=True)
    a.report.write_text(text)
    found = [n for n in SECTIONS if (a.outputs / n / "summary.json").exists()]
    print(f"wrote {a.report} ({len(found)} of {len(SECTIONS)} studies: {', '.join(found)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
