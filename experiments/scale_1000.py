#!/usr/bin/env python
"""Paper study "1000 nodes": throughput, AoI and BiDES's adaptive trigger rate.

1000 physics nodes, 20 per host (50 hosts, as the 200-node study's 20 per PC, so a
host's CPU load stays the same and the broker is what grows), MQTT QoS 1, 100 Hz
nominal triggers, 150-bit states. Reported per method: wire throughput in Mbps
(total and per link), AoI, latency, the broker's utilisation, and over time the
trigger rate in force (BiDES adapts it) and the achieved trigger rate.

A second variant, ``fast_broker``, runs BiDES with a broker four times faster
(1 µs per PUBLISH, 0.75 µs per delivery) to separate what broker saturation
does from what the alignment method does.

Paper (docs/concepts/paper.md):
208.4 Mbps, AoI 19 ± 3.7 ms, adaptive rate settles at 50 Hz.

Examples::

    python experiments/scale_1000.py                    # 20 s simulated, seed 1
    python experiments/scale_1000.py --quick --out /tmp/s1000

Outputs (``--out``, default ``out/scale_1000``): ``results.csv``, ``timeseries.csv``,
``summary.json``, ``metrics.png``, ``trigger_rate.png``, ``aoi_over_time.png``.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from sigma_lab import studies

from sigma_des.plots import rate_series

NAME = "scale_1000"
METHODS = ("none", "lockstep", "hlc", "bides")
PAPER = {"throughput_mbps": 208.4, "aoi_ms": "19 ± 3.7", "adaptive_rate_hz": 50}
FAST_BROKER = ("broker.publish_service=1e-6", "broker.delivery_service=0.75e-6")


#: Network-level study: the aircraft model only changes position metrics, so the cheap
#: point-mass model flies and the ideal-run fidelity metrics are off.
PINNED = ("dynamics=pointmass", "fidelity.enabled=false")


def overrides(quick: bool) -> list[str]:
    """Scenario overrides: 20 nodes per host, QoS 1, 100 Hz, 150-bit states."""
    base = ["f_trig=100.0", "net.qos=1", "payload_bits=150", *PINNED]
    if quick:
        return [*base, "nodes=160", "hosts=8", "duration=0.6", "warmup=0.2"]
    return [*base, "nodes=1000", "hosts=50", "duration=20.0", "warmup=2.0"]


def broker_capacity(sc: Any) -> dict[str, float]:
    """Offered broker load of the scenario and the trigger rate it can sustain.

    Per frame the broker serves one trigger PUBLISH with ``N`` deliveries and ``N``
    state PUBLISHes with one delivery each; commands add ``N`` PUBLISH + delivery
    every ``commands.every``-th alignment tick. Constant service times assumed
    (their configured value or mean).
    """

    def mean(d: Any) -> float:
        return float(d.value if d.dist == "constant" else d.mean)

    pub = mean(sc.broker.publish_service)
    dlv = mean(sc.broker.delivery_service)
    n = sc.nodes
    per_frame = pub + n * dlv + n * (pub + dlv)
    cmd_rate = sc.f_align / sc.commands.every if sc.commands.enabled else 0.0
    cmd_load = cmd_rate * n * (pub + dlv)
    return {
        "broker_s_per_frame": per_frame,
        "command_load": cmd_load,
        "offered_load_at_nominal": per_frame * sc.f_trig + cmd_load,
        "max_trigger_hz": max(0.0, (1.0 - cmd_load) / per_frame),
    }


def plots(study: studies.Study) -> None:
    """Throughput/AoI/broker bars, the trigger rate over time and AoI over time."""
    plt = studies.plot_setup(study.args.quick)
    out = study.args.out
    sc = study.variants["default"]
    tag = f"{sc.nodes} nodes on {sc.hosts} hosts, QoS {sc.net.qos}, nominal {sc.f_trig:g} Hz"
    fig, axs = plt.subplots(2, 3, figsize=(13, 7))
    panels = [
        ("throughput_mbps", 1.0, "wire throughput, all links (Mbps)"),
        ("aoi_mean", 1.0, "AoI mean (ms)"),
        ("latency_state_mean", 1.0, "state latency (ms)"),
        ("broker_util", 100.0, "broker utilisation (%)"),
        ("trigger_rate_hz", 1.0, "achieved trigger rate (Hz)"),
        ("f_trig_settled_hz", 1.0, "trigger rate in force, last quarter (Hz)"),
    ]
    studies.bar_panels(axs, study, "default", panels)
    axs.flat[0].axhline(PAPER["throughput_mbps"], color="k", ls="--", lw=1, label="paper 208.4")
    studies.legend_outside(axs.flat[0])
    axs.flat[1].axhline(19.0, color="k", ls="--", lw=1, label="paper 19 ms")
    studies.legend_outside(axs.flat[1])
    axs.flat[5].axhline(50.0, color="k", ls="--", lw=1, label="paper 50 Hz")
    studies.legend_outside(axs.flat[5])
    fig.suptitle(f"Scale study: {tag}")
    studies.save(fig, out, "metrics.png")

    fig, axs = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    studies.plot_rate(axs[1], study, "default", "latest_trigger", 0.5)
    for lab in study.labels("default"):
        ts = study.runs("default", lab)[0].timeseries
        if lab == "bides":
            axs[0].step(
                ts["t"],
                ts["f_trig"],
                where="post",
                color=studies.COLORS["bides"],
                label="bides (50 hosts, default broker)",
            )
    if "fast_broker" in study.variants:
        r = study.runs("fast_broker", "bides")[0]
        axs[0].step(
            r.timeseries["t"],
            r.timeseries["f_trig"],
            where="post",
            color="#98df8a",
            ls="--",
            label="bides, 4× faster broker" + (
                " (= default broker)" if np.array_equal(
                    r.timeseries["f_trig"], study.runs("default", "bides")[0].timeseries["f_trig"])
                else ""),
        )
        t, rate = rate_series(r.timeseries["t"], r.timeseries["latest_trigger"], 0.5)
        axs[1].plot(t, rate, color="#98df8a", lw=1, ls="--", label="bides, 4× faster broker")
    cap = study.extra["broker"]["default"]["max_trigger_hz"]
    for ax in axs:
        lo, top = studies.rate_ylim([sc.f_trig], [ln.get_ydata() for ln in ax.get_lines()])
        ax.set_ylim(lo, top)  # the data's range, not the broker's capacity
        above = " (above the axis)" if cap > top else ""
        ax.axhline(cap, color="k", ls=":", lw=1, label=f"broker capacity ≈ {cap:.0f} Hz{above}")
        ax.axhline(50.0, color="k", ls="--", lw=0.8, label="paper: settles at 50 Hz")
    axs[0].set_ylabel("trigger rate in force f_trig (Hz)")
    axs[0].set_title(f"BiDES adaptive trigger rate (seed {study.args.seeds[0]}) — {tag}")
    axs[1].set_ylabel("achieved trigger rate (Hz, 0.5 s windows)")
    axs[1].set_xlabel("simulated time (s)")
    axs[1].set_title("Achieved trigger rate per method")
    for ax in axs:
        studies.legend_outside(ax)
    studies.save(fig, out, "trigger_rate.png")

    fig, ax = plt.subplots(figsize=(11, 4.5))
    studies.plot_aoi_time(ax, study, "default")
    ax.set_yscale("log")
    ax.set_title(f"AoI over time (seed {study.args.seeds[0]}; band: max over nodes) — {tag}")
    studies.save(fig, out, "aoi_over_time.png")


TABLE = (
    ("throughput_mbps", "Mbps"),
    ("aoi_mean", "AoI ms"),
    ("aoi_std", "±std"),
    ("latency_state_mean", "lat ms"),
    ("broker_util", "broker"),
    ("trigger_rate_hz", "trig Hz"),
    ("f_trig_settled_hz", "f settled"),
    ("snapshot_rate_hz", "snap Hz"),
)


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.parse_args(NAME, __doc__, argv, default_seeds="1")
    ov = overrides(args.quick)
    variants = {
        "default": studies.load_scenario(None, ov),
        "fast_broker": studies.load_scenario(None, [*ov, *FAST_BROKER]),
    }
    specs = {
        "default": [studies.MethodSpec(m, m) for m in METHODS],
        "fast_broker": [studies.MethodSpec("bides", "bides")],
    }
    study = studies.run_study(NAME, args, variants, specs)
    study.extra["broker"] = {v: broker_capacity(sc) for v, sc in study.variants.items()}
    f_ts = [np.asarray(r.timeseries["f_trig"]) for r in study.runs("default", "bides")]
    study.extra["bides_f_trig_last_quarter"] = {
        "mean": float(np.mean([x[int(0.75 * x.size) :].mean() for x in f_ts])),
        "min": float(np.min([x[int(0.75 * x.size) :].min() for x in f_ts])),
        "max": float(np.max([x[int(0.75 * x.size) :].max() for x in f_ts])),
    }
    notes = [f"broker: {study.extra['broker']}"]
    return studies.finish(study, plots, PAPER, TABLE, notes)

if __name__ == "__main__":
    sys.exit(main())
