#!/usr/bin/env python
"""Paper study "latency tolerance": 10 nodes over a lossy, slow network.

``scenarios/latency_tolerance.toml``: 10 nodes, each on its own host, 30 % packet
loss and 30 ± 10 ms one-way delay on every physics host's link, physics (triggers)
at 100 Hz, alignment and rendering at 30 Hz. Two transports:

* ``datagram`` (the scenario file: QoS 0, a lost packet is gone — an
  application-level loss emulation);
* ``stream`` (TCP-like: a lost segment is resent after an RTO with exponential
  back-off and holds back everything behind it on its connection).

Reported per method (none, lockstep, hlc, bides): AoI over time and its
distribution, the displacement ("flicker") of the shown swarm — the frame spread
of the shown snapshot as time, and the position error of the shown states against
the true positions at the snapshot's frame — and the achieved frame rates.

Paper (docs/concepts/paper.md):
without alignment the swarm flickers (30–90 ms displacement),
HLC mean AoI ≈ 70 ms, BiDES ≈ 38 ms at a stable 20 Hz.

Examples::

    python experiments/latency_tolerance.py             # 30 s simulated, seeds 1,2,3
    python experiments/latency_tolerance.py --quick --out /tmp/lt

Outputs (``--out``, default ``out/latency_tolerance``): ``results.csv``,
``timeseries.csv``, ``summary.json``, ``aoi_over_time.png``, ``aoi_distribution.png``,
``flicker.png``, ``frame_rate.png``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from sigma_lab import studies

NAME = "latency_tolerance"
METHODS = ("none", "lockstep", "hlc", "bides")
SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "latency_tolerance.toml"
PAPER = {
    "none_displacement_ms": "30-90",
    "hlc_aoi_ms": 70,
    "bides_aoi_ms": 38,
    "bides_rate_hz": 20,
}
SPREAD_SMOOTH_S = 0.2  # spread alternates tick by tick: plot its moving mean
VARIANTS = {"datagram": ["net.transport=datagram"], "stream": ["net.transport=stream"]}
#: The 6-DoF quadrotor flies (its manoeuvres make the position error of a stale or
#: extrapolated state visible; straight point-mass flight would hide it).
PINNED = ("dynamics=quadrotor",)


def overrides(quick: bool) -> list[str]:
    """Run length: the scenario file's 30 s, or 2 s for ``--quick``."""
    return ["duration=2.0", "warmup=0.5"] if quick else []


def plots(study: studies.Study) -> None:
    """AoI over time and distribution, flicker (displacement), frame rates."""
    plt = studies.plot_setup(study.args.quick)
    out = study.args.out
    variants = list(study.variants)
    seed = study.args.seeds[0]

    fig, axs = plt.subplots(len(variants), 1, figsize=(11, 3.8 * len(variants)))
    for ax, v in zip(np.atleast_1d(axs), variants, strict=True):
        studies.plot_aoi_time(ax, study, v)
        ax.set_yscale("log")
        ax.set_title(f"AoI over time — {v} transport (seed {seed}; band: max over nodes)")
    studies.save(fig, out, "aoi_over_time.png")

    fig, axs = plt.subplots(1, len(variants), figsize=(6 * len(variants), 4.5))
    for ax, v in zip(np.atleast_1d(axs), variants, strict=True):
        studies.plot_aoi_dist(ax, study, v)
        ax.set_yscale("log")
        ax.axhline(70, color=studies.COLORS["hlc"], ls="--", lw=0.8, label="paper HLC 70 ms")
        ax.axhline(38, color=studies.COLORS["bides"], ls="--", lw=0.8, label="paper BiDES 38 ms")
        studies.legend_outside(ax, fontsize=7)
        ax.set_title(f"AoI distribution — {v} transport")
    studies.save(fig, out, "aoi_distribution.png")

    fig, axs = plt.subplots(2, 2, figsize=(13, 8))
    for col, v in enumerate(variants[:2]):
        ax = axs[0, col]
        series = {}
        for lab in study.labels(v):
            ts = study.runs(v, lab)[0].timeseries
            disp = np.asarray(ts["spread"], float) / np.asarray(ts["f_trig"], float) * 1000.0
            n = max(1, round(SPREAD_SMOOTH_S * study.variants[v].f_render))
            series[lab] = (np.asarray(ts["t"], float), studies.moving_average(disp, n))
        studies.plot_lines(ax, series, lw=1.0)
        ax.axhspan(30, 90, color="k", alpha=0.06, label="paper: 30–90 ms without alignment")
        ax.set_xlabel("simulated time (s)")
        ax.set_title(f"Frame spread as time — {v} (seed {seed})")
        ax.set_ylabel(f"displacement (ms, {SPREAD_SMOOTH_S:g} s mean)")
        studies.legend_outside(ax)
        ax = axs[1, col]
        labels = study.labels(v)
        x = np.arange(len(labels))
        for off, metric, name in ((-0.2, "pos_err_mean", "mean"), (0.2, "pos_err_max", "max")):
            ys = [float(np.nanmean(study.values(v, lab, metric))) for lab in labels]
            ax.bar(
                x + off,
                ys,
                width=0.4,
                label=f"position error {name}",
                color=[studies.COLORS.get(lab) for lab in labels],
                alpha=1.0 if name == "mean" else 0.45,
            )
        ax.set_xticks(x, labels)
        ax.set_ylabel("shown vs true position (m)")
        ax.set_title(f"Positional flicker — {v} (left: mean, right: max)")
    studies.save(fig, out, "flicker.png")

    fig, axs = plt.subplots(2, 2, figsize=(13, 8))
    for col, v in enumerate(variants[:2]):
        ax = axs[0, col]
        studies.plot_rate(ax, study, v, "aligned_frame", 1.0)
        ax.axhline(20, color="k", ls="--", lw=0.8, label="paper BiDES 20 Hz")
        ax.set_xlabel("simulated time (s)")
        ax.set_ylabel("aligned frames advanced per second (1 s windows)")
        ax.set_title(f"Aligned frame rate over time — {v} (seed {seed})")
        f_set = study.variants[v].f_trig
        ax.axhline(f_set, color="k", ls=":", lw=0.8, label=f"set trigger rate {f_set:g} Hz")
        ax.set_ylim(*studies.rate_ylim([f_set], [ln.get_ydata() for ln in ax.get_lines()]))
        studies.legend_outside(ax)
        ax = axs[1, col]
        studies.bar_metric(ax, study, v, "snapshot_rate_hz")
        ax.set_ylabel("new snapshots shown per second (Hz)")
        ax.set_title(f"Rendered snapshot rate (render at 30 Hz) — {v}")
    studies.save(fig, out, "frame_rate.png")


TABLE = (
    ("aoi_mean", "AoI ms"),
    ("aoi_std", "±std"),
    ("aoi_p99", "p99"),
    ("latency_state_mean", "lat ms"),
    ("displacement_mean_ms", "disp ms"),
    ("displacement_max_ms", "disp max"),
    ("pos_err_mean", "pos err m"),
    ("snapshot_rate_hz", "snap Hz"),
    ("aligned_rate_hz", "frames/s"),
    ("trigger_rate_hz", "trig Hz"),
    ("extrapolated_frac", "extrap"),
)


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.parse_args(NAME, __doc__, argv)
    variants = {
        v: studies.load_scenario(SCENARIO, [*ov, *PINNED, *overrides(args.quick)])
        for v, ov in VARIANTS.items()
    }
    specs = {v: [studies.MethodSpec(m, m) for m in METHODS] for v in VARIANTS}
    return studies.finish(studies.run_study(NAME, args, variants, specs), plots, PAPER, TABLE)

if __name__ == "__main__":
    sys.exit(main())
