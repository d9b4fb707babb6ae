#!/usr/bin/env python
"""Fault study: what each alignment method does when a node or a host misbehaves.

Three variants of one swarm (50 nodes, 10 per host on 5 hosts, 100 Hz, QoS 1 over
the stream transport; a physics step costs 3 ± 0.5 ms so that a 5× slower node
really cannot keep up with 10 ms frames):

* ``crash`` — node 7 stops for good at the fault start;
* ``slow`` — node 7's steps take 5× longer for 6 s (a straggler);
* ``degrade`` — host 1's link gets 50 ms extra one-way delay and 30 % extra loss
  for 2 s.

Methods: none, lockstep (no eviction: a dead node stalls everyone), lockstep_evict
(``lockstep.eviction_timeout = 0.2`` s), hlc (a silent node is dropped after the
0.5 s liveness timeout) and bides (lag exclusion with Θ_lag = 3 frames, hole
filling, adaptive trigger rate, time warp).

Plots: per variant, AoI over time and the aligned frame rate / trigger rate over
time with the fault window shaded, and bars of AoI and aligned rate before,
during and after the fault.

Examples::

    python experiments/faults.py                    # 15 s simulated, seeds 1,2,3
    python experiments/faults.py --quick --out /tmp/faults

Outputs (``--out``, default ``out/faults``): ``results.csv``, ``timeseries.csv``,
``summary.json``, ``faults_timeseries.png``, ``faults_windows.png``.
"""

from __future__ import annotations

import sys

import numpy as np
from sigma_lab import studies

from sigma_des.plots import rate_series

NAME = "faults"
NODE = 7
HOST = 1
EVICT = 0.2
SPECS = [
    studies.MethodSpec("none", "none"),
    studies.MethodSpec("lockstep", "lockstep"),
    studies.MethodSpec("lockstep_evict", "lockstep", (f"lockstep.eviction_timeout={EVICT}",)),
    studies.MethodSpec("hlc", "hlc"),
    studies.MethodSpec("bides", "bides"),
]


def timing(quick: bool) -> dict[str, float]:
    """Run length and fault windows (s)."""
    if quick:
        return {"duration": 1.3, "warmup": 0.2, "start": 0.5, "slow_end": 1.0, "degrade_end": 0.8}
    return {"duration": 15.0, "warmup": 1.0, "start": 5.0, "slow_end": 11.0, "degrade_end": 7.0}


def base_overrides(quick: bool) -> list[str]:
    """The swarm shared by all variants."""
    tm = timing(quick)
    size = ["nodes=12", "hosts=3"] if quick else ["nodes=50", "hosts=5"]
    return [
        *size,
        "f_trig=100.0",
        "net.qos=1",
        "net.transport=stream",
        "compute.step_time={dist='lognormal', mean=0.003, std=0.0005}",
        f"duration={tm['duration']}",
        f"warmup={tm['warmup']}",
        # AoI and rates are studied here: the cheap point-mass model, no ideal run
        "dynamics=pointmass",
        "fidelity.enabled=false",
    ]


def fault_overrides(quick: bool) -> dict[str, tuple[list[str], tuple[float, float]]]:
    """Per variant: its ``faults=[...]`` override and the fault window (start, end)."""
    tm = timing(quick)
    s, dur = tm["start"], tm["duration"]
    return {
        "crash": ([f"faults=[{{kind='crash', node={NODE}, start={s}}}]"], (s, dur)),
        "slow": (
            [f"faults=[{{kind='slow', node={NODE}, start={s}, end={tm['slow_end']}, factor=5.0}}]"],
            (s, tm["slow_end"]),
        ),
        "degrade": (
            [
                f"faults=[{{kind='degrade', host={HOST}, start={s}, end={tm['degrade_end']}, "
                "extra_delay=0.05, extra_loss=0.3}]"
            ],
            (s, tm["degrade_end"]),
        ),
    }


def plots(study: studies.Study, windows: dict[str, tuple[float, float]]) -> None:
    """AoI and aligned frame rate over time per variant; before/during/after bars."""
    plt = studies.plot_setup(study.args.quick)
    out = study.args.out
    variants = list(study.variants)
    seed = study.args.seeds[0]
    fig, axs = plt.subplots(len(variants), 2, figsize=(14, 3.8 * len(variants)), squeeze=False)
    for row, v in enumerate(variants):
        a, b = windows[v]
        ax_aoi, ax_rate = axs[row]
        aoi, rates = {}, {}
        for lab in study.labels(v):
            ts = study.runs(v, lab)[0].timeseries
            aoi[lab] = (np.asarray(ts["t"]), np.asarray(ts["aoi_mean"]) * 1000.0)
            rates[lab] = rate_series(ts["t"], ts["aligned_frame"], window=0.25)
        studies.plot_lines(ax_aoi, aoi, lw=1.0)
        studies.plot_lines(ax_rate, rates, ": aligned frames/s", lw=1.0)
        if "bides" in aoi:
            ts = study.runs(v, "bides")[0].timeseries
            ax_rate.step(ts["t"], ts["f_trig"], where="post", color="k", ls=":", lw=1,
                         label="bides: trigger rate in force")
        ax_rate.set_ylim(*studies.rate_ylim([study.variants[v].f_trig],
                                            [y for _, y in rates.values()]))
        for ax in (ax_aoi, ax_rate):
            ax.axvspan(a, b, color="orange", alpha=0.15, label="fault window")
            ax.set_xlabel("simulated time (s)")
        ax_aoi.set_yscale("log")
        ax_aoi.set_ylabel("AoI, mean over nodes (ms)")
        ax_aoi.set_title(f"{v}: AoI over time, mean over all nodes incl. the faulty (seed {seed})")
        ax_rate.set_ylabel("rate (Hz; 0.25 s windows)")
        ax_rate.set_title(f"{v}: aligned frame rate and BiDES trigger rate")
        studies.legend_outside(ax_aoi, fontsize=7)
        studies.legend_outside(ax_rate, fontsize=7)
    studies.save(fig, out, "faults_timeseries.png")

    fig, axs = plt.subplots(2, len(variants), figsize=(5 * len(variants), 7), squeeze=False)
    phases = ("before", "during", "after")
    for col, v in enumerate(variants):
        labels = study.labels(v)
        x = np.arange(len(labels))
        for row, (key, unit) in enumerate(
            (("aoi_{}_ms", "mean AoI (ms)"), ("aligned_rate_{}_hz", "aligned frames/s (Hz)"))
        ):
            ax = axs[row, col]
            for j, ph in enumerate(phases):
                ys = [study.extra["windows"][v][lab][key.format(ph)] for lab in labels]
                ax.bar(
                    x + (j - 1) * 0.27,
                    ys,
                    width=0.27,
                    label=ph,
                    color=["#9ecae1", "#fd8d3c", "#74c476"][j],
                )
            ax.set_xticks(x, labels, rotation=20)
            ax.set_ylabel(unit)
            ax.set_title(f"{v}: {unit.split(' (')[0]} before / during / after")
            if row == 0:
                ax.set_yscale("log")
            studies.legend_outside(ax, fontsize=7)
    studies.save(fig, out, "faults_windows.png")


TABLE = (
    ("aoi_mean", "AoI ms"),
    ("aoi_max", "AoI max"),
    ("trigger_rate_hz", "trig Hz"),
    ("snapshot_rate_hz", "snap Hz"),
    ("stall_time_s", "stall s"),
    ("evicted", "evicted"),
    ("extrapolated_frac", "extrap"),
    ("spread_mean", "spread"),
    ("rollbacks", "rollbk"),
)


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.parse_args(NAME, __doc__, argv)
    base = base_overrides(args.quick)
    fo = fault_overrides(args.quick)
    variants = {v: studies.load_scenario(None, [*base, *ov]) for v, (ov, _) in fo.items()}
    specs = {v: SPECS for v in fo}
    study = studies.run_study(NAME, args, variants, specs)
    windows = {v: w for v, (_, w) in fo.items()}
    study.extra["windows"] = {
        v: {
            lab: studies.seed_means(
                [studies.window_stats(r.timeseries, *windows[v]) for r in study.runs(v, lab)]
            )
            for lab in study.labels(v)
        }
        for v in study.variants
    }
    study.extra["fault_window_s"] = windows
    study.extra["target"] = {"node": NODE, "host": HOST, "eviction_timeout_s": EVICT}
    return studies.finish(study, lambda st: plots(st, windows), None, TABLE)



if __name__ == "__main__":
    sys.exit(main())
