"""The calibration's report as readable lines, and the calibrated scenario as TOML."""

from __future__ import annotations

import math
from typing import Any

from sigma_des.config import Scenario, to_toml

__all__ = ["calibrated_toml", "report_lines"]


def report_lines(report: dict[str, Any]) -> list[str]:
    """The report as readable lines: the fitted figures (``key = value``), the CPU
    demands, the in-sample errors (flagged cells marked) and the warnings."""
    lines = [f"{k} = {v}" for k, v in report.items() if not isinstance(v, list | dict)]
    for m, cores in report.get("background_cores", {}).items():
        lines.append(f"background_cores.{m} = {cores:.3f} (CPU other processes used)")
    for r in report.get("cpu_demands", []):
        lines.append(f"cpu demand {r['method']}/{r['process']}: {r['demand_s'] * 1e6:.1f} "
                     f"µs per message ({r['messages']:.0f} messages, busy {r['busy_s']:.3f} s "
                     f"of {r['window_s']:.2f} s, idle rate {r['idle_rate']:.4f})")
    for what, runs in report.get("parameter_sources", {}).items():
        lines.append(f"from {', '.join(runs)}: {what}")
    for r in report.get("in_sample", []):
        unit = "pp" if r["metric"] == "missed_frac" else "%"
        run = f"{r['run']} " if r.get("run") and "parameter_sources" in report else ""
        lines.append(f"in-sample {run}{r['method']} {r['metric']}: live {r['live']:.4g}, DES "
                     f"{r['des']:.4g}, error {100 * r['error']:+.1f} {unit}"
                     + ("  > 10: FLAGGED" if r["flagged"] else ""))
    cells = [r for r in report.get("in_sample", []) if math.isfinite(r["error"])]
    if cells:
        ok = sum(not r["flagged"] for r in cells)
        lines.append(f"in-sample: {ok} of {len(cells)} cells within 10 % (10 pp)")
        lines += _apart_lines(report, len(cells) - ok)
    lines += [f"warning: {w}" for w in report.get("warnings", [])]
    return lines


def _apart_lines(report: dict[str, Any], flagged: int) -> list[str]:
    """The flagged cells no calibration could bring within 10 % of every run: live's
    repeats of their setting too far apart (:func:`~sigma_des.calibrate.insample.repeats_apart`)."""
    from sigma_des.calibrate.insample import apart_text, repeats_apart

    apart = repeats_apart(report)
    if not apart:
        return []
    lines = [f"in-sample: {sum(g['flagged'] for g in apart)} of the {flagged} flagged cells "
             "are runs of a setting whose live repeats are more than 22 % (20 pp) apart: no "
             "one value is within 10 % of each"]
    lines += [f"live repeats apart: {apart_text(g)}" for g in apart]
    return lines


def calibrated_toml(sc: Scenario, report: dict[str, Any]) -> str:
    """The calibrated scenario as TOML, the report (:func:`report_lines`) as a comment
    header."""
    head = ["# calibrated by `sigma-des calibrate` from a live run"]
    head += [f"# {line}" for line in report_lines(report)]
    return "\n".join(head) + "\n" + to_toml(sc)
