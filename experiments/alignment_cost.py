#!/usr/bin/env python
"""Paper study "alignment cost": wall time of one alignment step, as implemented.

Times, with ``time.perf_counter`` over repeats (median and p95), for n = 100, 300,
1000, 3000, 10000 nodes:

* ``bides`` — Algorithm 1 over ring buffers with k = 30, filled the way a running
  swarm leaves them; ``hlc`` — one alignment tick of the HLC consumer; ``lockstep``
  — the Lock-Step barrier (details: :mod:`sigma_lab.studies.align_cost`).

The cost of receiving the states (``ingest``: ring-buffer inserts, HLC buffer
pushes, barrier bookkeeping, one Python call per state) is timed separately from
the alignment step itself (``align``).

Paper (docs/concepts/paper.md):
Algorithm 1 at n = 1000, k = 30 takes < 8 ms.
Timings depend on the machine and its load; nothing asserts on them.

Examples::

    python experiments/alignment_cost.py                 # n up to 10000
    python experiments/alignment_cost.py --quick --out /tmp/ac

Outputs (``--out``, default ``out/alignment_cost``): ``results.csv`` (tidy: one row per
n × method × metric), ``summary.json``, ``cost_vs_n.png``.
"""

from __future__ import annotations

import hashlib
import json
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np
from sigma_lab import studies
from sigma_lab.studies.align_cost import (
    BENCHES,
    F_ALIGN,
    F_TRIG,
    HOLE_P,
    NAME,
    THETA_LAG,
    WHAT,
    K,
    record,
)

import sigma_des

PAPER = {"bides_align_ms_at_1000": "< 8"}


def plot(out: Path, table: dict[str, Any], ns: list[int], fast: bool) -> None:
    """Cost vs n, log-log: median with a p95 whisker, the paper's bound and O(n)."""
    plt = studies.plot_setup(fast)
    fig, axs = plt.subplots(1, 2, figsize=(13, 5), sharey=True)
    for ax, part in zip(axs, ("align", "ingest"), strict=True):
        for i, method in enumerate(BENCHES):
            med = np.array([table[str(n)][method][f"{part}_median_ms"] for n in ns])
            p95 = np.array([table[str(n)][method][f"{part}_p95_ms"] for n in ns])
            kw = studies.line_kw(method, i, len(ns))
            ax.plot(ns, med, label=f"{method}: {WHAT[(method, part)]}", **kw)
            ax.vlines(ns, med, p95, color=kw["color"], alpha=0.6)
        ref = np.array(ns, dtype=float)
        b = table[str(ns[0])]["bides"][f"{part}_median_ms"]
        ax.plot(ref, b * ref / ref[0], ":", color="k", lw=0.8, label="∝ n (reference)")
        if part == "align":
            ax.scatter(
                [1000],
                [8.0],
                marker="*",
                s=140,
                color="k",
                zorder=5,
                label="paper: Algorithm 1 < 8 ms at n = 1000",
            )
            ax.axhline(
                1000 / F_ALIGN,
                color="k",
                ls="--",
                lw=0.8,
                label=f"one alignment period at {F_ALIGN:g} Hz",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("nodes n")
    studies.legend_outside(axs[0], below=True, fontsize=7)
    studies.legend_outside(axs[1], below=True, fontsize=7)
    axs[0].set_ylabel("wall time per step (ms)")
    axs[0].set_title("Alignment step")
    axs[1].set_title("Receiving the states (per frame / per tick)")
    fig.suptitle(f"Cost of alignment as implemented (k = {K}, Python "
                 f"{platform.python_version()}; line = median, whisker to p95)")
    studies.save(fig, out, "cost_vs_n.png")


def main(argv: list[str] | None = None) -> int:
    """Time every method at every n and write the outputs."""
    args = studies.parse_args(NAME, __doc__, argv, "1")
    ns = [100, 300, 1000] if args.quick else [100, 300, 1000, 3000, 10000]
    budget = 0.1 if args.quick else 2.0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    params = {
        "k": K,
        "theta_lag": THETA_LAG,
        "hole_p": HOLE_P,
        "f_trig": F_TRIG,
        "f_align": F_ALIGN,
        "ns": ns,
        "budget_s": budget,
    }
    chash = hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:12]
    table: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    for seed in args.seeds:
        for n in ns:
            for method, bench in BENCHES.items():
                times = bench(n, seed, budget)
                cell = table.setdefault(str(n), {}).setdefault(method, {})
                rows += record(times, cell, n, seed, method, chash)
    # several seeds: the median over seeds of each figure
    agg = {
        n: {m: {k: float(np.median(v)) for k, v in c.items()} for m, c in d.items()}
        for n, d in table.items()
    }
    studies.write_rows(out, rows)
    plot(out, agg, ns, args.quick)
    studies.write_summary(
        out,
        {
            "study": NAME,
            "command": studies.command_line(NAME),
            "quick": bool(args.quick),
            "seeds": list(args.seeds),
            "version": sigma_des.__version__,
            "paper": PAPER,
            "params": params,
            "config_hash": chash,
            "machine": {
                "python": platform.python_version(),
                "platform": platform.platform(),
                "processor": platform.processor() or platform.machine(),
            },
            "what": {f"{m}.{p}": w for (m, p), w in WHAT.items()},
            "cost": agg,
            "plots": sorted(p.name for p in out.glob("*.png")),
        },
    )
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
