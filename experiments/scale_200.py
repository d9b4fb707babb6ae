#!/usr/bin/env python
"""Paper study "200 nodes": none / Lock-Step / HLC / BiDES at the paper's scale.

200 physics nodes on 10 hosts (20 per host, as the paper's 10 PCs), MQTT QoS 1 over
the TCP-like stream transport, 100 Hz triggers, 150-bit states, rendering at 60 Hz.
Reported per method: state latency, AoI (mean ± std and its distribution), the
alignment server's buffer memory, wire throughput and the achieved frame rates,
plus AoI over time.

Paper (docs/concepts/paper.md):
BiDES latency 3.5 ms, AoI 8.7 ± 1.7 ms, < 650 MB per host,
rendering > 60 Hz; the Lock-Step baseline (Gazebo/FastDDS) 62 ± 15 ms at 200 nodes.

Examples::

    python experiments/scale_200.py                    # 60 s simulated, seeds 1,2,3
    python experiments/scale_200.py --quick --out /tmp/s200
    python experiments/scale_200.py --seeds 4,5 --jobs 2

Outputs (``--out``, default ``out/scale_200``): ``results.csv``, ``timeseries.csv``,
``summary.json``, ``metrics.png``, ``aoi_distribution.png``, ``aoi_over_time.png``.
"""

from __future__ import annotations

import sys

from sigma_lab import studies

NAME = "scale_200"
METHODS = ("none", "lockstep", "hlc", "bides")
PAPER = {
    "bides_latency_ms": 3.5,
    "bides_aoi_ms": "8.7 ± 1.7",
    "memory_per_host_mb": "< 650",
    "render_hz": "> 60",
    "lockstep_aoi_ms": "62 ± 15 (Gazebo/FastDDS, 200 nodes)",
}


#: Network-level study: the aircraft model only changes position metrics, so the cheap
#: point-mass model flies and the ideal-run fidelity metrics are off.
PINNED = ("dynamics=pointmass", "fidelity.enabled=false")


def overrides(quick: bool) -> list[str]:
    """Scenario overrides of the study (defaults already are 10 hosts, QoS 1, 100 Hz, 150 bit)."""
    base = [
        "hosts=10",
        "f_trig=100.0",
        "net.qos=1",
        "payload_bits=150",
        "f_render=60.0",
        *PINNED,
    ]
    if quick:
        return [*base, "nodes=100", "duration=0.8", "warmup=0.2"]
    return [*base, "nodes=200", "duration=60.0", "warmup=2.0"]


def plots(study: studies.Study) -> None:
    """Bar charts of the headline metrics, the AoI distribution and AoI over time."""
    plt = studies.plot_setup(study.args.quick)
    out = study.args.out
    sc = study.variants["default"]
    tag = f"{sc.nodes} nodes, {sc.hosts} hosts, QoS {sc.net.qos}, {sc.f_trig:g} Hz"
    fig, axs = plt.subplots(2, 3, figsize=(13, 7))
    panels = [
        ("latency_state_mean", 1.0, "state latency, publish → server (ms)"),
        ("aoi_mean", 1.0, "AoI mean (ms); bar = mean over seeds"),
        ("buffer_bytes_peak", 1 / 1024, "alignment-server buffer peak (KiB)"),
        ("throughput_mbps", 1.0, "wire throughput, all links (Mbps)"),
        ("snapshot_rate_hz", 1.0, "new aligned snapshots (Hz)"),
        ("trigger_rate_hz", 1.0, "achieved trigger rate (Hz)"),
    ]
    studies.bar_panels(axs, study, "default", panels)
    # AoI std within the run as whiskers on the AoI panel
    ax = axs.flat[1]
    labels = study.labels("default")
    for i, lab in enumerate(labels):
        m = float(study.values("default", lab, "aoi_mean").mean())
        s = float(study.values("default", lab, "aoi_std").mean())
        ax.errorbar(i + 0.2, m, yerr=s, fmt="o", color="k", ms=3, capsize=3)
    ax.set_title("AoI, mean (black: ± AoI std over samples)")
    fig.suptitle(f"Scale study: {tag}")
    studies.save(fig, out, "metrics.png")

    fig, ax = plt.subplots(figsize=(8, 4.5))
    studies.plot_aoi_dist(ax, study, "default")
    ax.set_title(f"AoI distribution (violins: per-render-tick mean AoI) — {tag}")
    studies.save(fig, out, "aoi_distribution.png")

    fig, ax = plt.subplots(figsize=(11, 4.5))
    studies.plot_aoi_time(ax, study, "default")
    ax.set_title(f"AoI over time (seed {study.args.seeds[0]}; band: max over nodes) — {tag}")
    studies.save(fig, out, "aoi_over_time.png")


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.parse_args(NAME, __doc__, argv)
    variants = {"default": studies.load_scenario(None, overrides(args.quick))}
    specs = {"default": [studies.MethodSpec(m, m) for m in METHODS]}
    return studies.finish(studies.run_study(NAME, args, variants, specs), plots, PAPER, TABLE)

TABLE = (
    ("latency_state_mean", "lat ms"),
    ("aoi_mean", "AoI ms"),
    ("aoi_std", "±std"),
    ("aoi_p99", "p99"),
    ("buffer_bytes_peak", "buf B"),
    ("throughput_mbps", "Mbps"),
    ("snapshot_rate_hz", "snap Hz"),
    ("trigger_rate_hz", "trig Hz"),
    ("spread_mean", "spread"),
)

if __name__ == "__main__":
    sys.exit(main())
