#!/usr/bin/env python
"""Calibrate the DES on one live run, then predict live runs it did not see.

1. Live calibration run: N = 20 on 4 hosts, BiDES, 5 s (scenario defaults
   otherwise: QoS 1, stream transport, formation commands, the client shim applying
   the default 250 µs per-hop latency, each node's drawn step time on top of its
   real step).
2. ``sigma_des.live.calibrate`` fits per-hop latency, broker delivery service,
   server receive queueing and node step time, and sets the live wire sizes.
3. Held-out targets, each run live (all four methods) and predicted by the DES
   from the calibrated scenario with only the target's own keys changed:
   ``n10`` (N = 10, 2 hosts), ``n50`` (N = 50, 4 hosts), ``n20`` (N = 20: the
   calibration N, so for none/Lock-Step/HLC it is "another method"; for BiDES a
   re-run), ``loss10`` (N = 20, 10 % Bernoulli loss on every host link).
4. Per method and target: live and DES mean AoI, p99 AoI, mean state latency,
   achieved trigger rate, snapshot rate and Mbps, with the relative error
   (DES - live) / live; a plot of DES against live.

Outputs in ``--out`` (default ``/work/out/live_vs_des``): ``comparison.csv`` (tidy),
``comparison.md`` (tables per method), ``calibration.json``, ``cal/`` (the
calibrated scenario and its sample files), ``live_<target>/`` (each live run's
``sigma-des live --out`` files) and ``live_vs_des.png``.

    python experiments/live_vs_des.py                 # the full study (~3 min of live runs)
    python experiments/live_vs_des.py --quick --out /tmp/lvd   # tiny (tests)
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

from sigma_des.api import compare
from sigma_des.config import METHODS, load
from sigma_des.live.calibrate import calibrate, calibrated_toml, for_target
from sigma_des.live.messages import write_messages
from sigma_des.live.runner import LiveOptions, run_live
from sigma_des.plotstyle import legend_outside, line_kw, metric_title

METRICS = ("aoi_mean", "aoi_p99", "latency_state_mean", "trigger_rate_hz",
           "snapshot_rate_hz", "throughput_mbps")
BASE = ["fidelity.enabled=false"]


def _live(sets: list[str], methods: list[str], out: Path) -> dict[str, dict[str, float]]:
    sc = load(None, BASE + sets)
    res, msgs, _ = run_live(sc, methods, LiveOptions())
    res.write(out)
    write_messages(msgs, out)
    return res.methods


def _rel(des: float, live: float) -> float:
    if not (math.isfinite(des) and math.isfinite(live)) or live == 0:
        return math.nan
    return (des - live) / live


def _plot(rows: list[dict[str, Any]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained")
    for ax, metric in zip(axes, ("aoi_mean", "latency_state_mean"), strict=True):
        sel = [r for r in rows if r["metric"] == metric]
        targets = sorted({r["target"] for r in sel})
        for ti, tgt in enumerate(targets):  # one target filled, the others hollow
            for r in (r for r in sel if r["target"] == tgt):
                kw = line_kw(r["method"], n_points=1)
                ax.scatter(r["live"], r["des"], marker=kw["marker"], s=40,
                           color=kw["color"], facecolors=kw["color"] if ti == 0 else "none",
                           label=f"{r['method']} ({tgt})")
        hi = max([max(r["live"], r["des"]) for r in sel if math.isfinite(r["des"])] + [1.0])
        ax.plot([0, hi], [0, hi], "k-", lw=0.8)
        ax.fill_between([0, hi], [0, 0.85 * hi], [0, 1.15 * hi], color="0.9", zorder=0)
        ax.set_xlabel(f"live {metric} (ms)")
        ax.set_ylabel(f"DES {metric} (ms)")
        ax.set_title(f"{metric_title(metric)}: DES vs live (band ±15 %)")
    legend_outside(axes[1], fontsize=8)
    fig.savefig(out / "live_vs_des.png", dpi=110)
    plt.close(fig)


def _markdown(rows: list[dict[str, Any]], load_avg: dict[str, float]) -> str:
    lines = []
    for m in METHODS:
        sel = [r for r in rows if r["method"] == m]
        if not sel:
            continue
        lines += [f"#### {m}", "", "| target | " + " | ".join(METRICS) + " |",
                  "|---|" + "---|" * len(METRICS)]
        for tgt in dict.fromkeys(r["target"] for r in sel):
            cells = []
            for metric in METRICS:
                r = next(r for r in sel if r["target"] == tgt and r["metric"] == metric)
                cells.append(f"{r['live']:.2f} / {r['des']:.2f} ({100 * r['rel_err']:+.0f} %)")
            lines.append(f"| {tgt} (load {load_avg[tgt]:.1f}) | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the study; write the outputs into ``--out``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="N = 4..6, 1 s, two methods")
    p.add_argument("--out", default="/work/out/live_vs_des")
    p.add_argument("--duration", type=float, default=5.0)
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    dur = 1.0 if a.quick else a.duration
    common = [f"duration={dur}", f"warmup={0.2 if a.quick else 1.0}"]
    methods = ["none", "bides"] if a.quick else list(METHODS)
    cal_sets = (["nodes=4", "hosts=2"] if a.quick else ["nodes=20", "hosts=4"]) + common
    targets = ({"n6": ["nodes=6", "hosts=2"]} if a.quick else {
        "n10": ["nodes=10", "hosts=2"],
        "n20": ["nodes=20", "hosts=4"],
        "n50": ["nodes=50", "hosts=4"],
        "loss10": ["nodes=20", "hosts=4", "net.host_link.loss.p=0.1"],
    })
    print(f"calibration run: {cal_sets}, bides", file=sys.stderr, flush=True)
    _live(cal_sets, ["bides"], out / "live_calibration")
    cal, report = calibrate(out / "live_calibration", out / "cal")
    (out / "cal" / "calibrated.toml").write_text(calibrated_toml(cal, report))
    (out / "calibration.json").write_text(json.dumps(report, indent=2) + "\n")
    rows: list[dict[str, Any]] = []
    load_avg: dict[str, float] = {}
    for tgt, sets in targets.items():
        print(f"target {tgt}: live", file=sys.stderr, flush=True)
        before = os.getloadavg()[0]
        live = _live(sets + common, methods, out / f"live_{tgt}")
        load_avg[tgt] = (before + os.getloadavg()[0]) / 2
        des_sc = for_target(cal, report, sets + common)
        des = compare(des_sc, methods, progress=False).methods
        for m in methods:
            for metric in METRICS:
                lv, dv = float(live[m][metric]), float(des[m][metric])
                rows.append({"target": tgt, "method": m, "metric": metric, "live": lv,
                             "des": dv, "rel_err": _rel(dv, lv), "load_avg": load_avg[tgt]})
    with (out / "comparison.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    md = _markdown(rows, load_avg)
    (out / "comparison.md").write_text(md)
    _plot(rows, out)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
