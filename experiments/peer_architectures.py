#!/usr/bin/env python
"""Paper study "peer architectures" (its Fig. 16, Tables I/IV): SIGMA vs Gazebo vs AirSim.

Four architectures on one workload and on identical draws (same seeds; every
random number is keyed by name, so the shared parts draw the same values):

* ``bides_mqtt``    — SIGMA: BiDES over the MQTT broker (QoS 1 over TCP);
* ``lockstep_mqtt`` — our Lock-Step over the same broker;
* ``lockstep_dds``  — Gazebo-style: Lock-Step over DDS/RTPS (ROS 2 on Fast DDS
  defaults; ``scenarios/gazebo_lockstep_dds.toml``);
* ``rpc``           — AirSim-style: synchronous per-vehicle calls each frame and a
  game thread shared by calls and rendering (``scenarios/airsim_rpc.toml``);

plus ``lockstep_dds_noscan``: Gazebo-style with ``dds.executor_per_entity = 0`` (an
executor that does not scan its entities per message), to show which DDS cost
drives the degradation.

Swarm size N = 20 … 300 on 10 physics hosts, 100 Hz nominal, 150-bit states,
rendering sampled at 60 Hz. Reported: AoI mean ± std and p99, state latency,
achieved frame rate (triggers/s; ``rtf`` = achieved / nominal), stalls, and the
smallest N at which each architecture is *unstable*, defined as: the achieved
frame rate is below half the nominal rate (real-time factor < 0.5), or the run
has a stall (a gap > ``stall_threshold`` = 100 ms without a new snapshot).

Paper: Gazebo AoI 12 ms at 60 nodes rising to 62 ± 15 ms at 200, unstable beyond
~100 nodes; AirSim AoI 23–45 ms with a node limit of 20–50; SIGMA 8.7 ± 1.7 ms.

Examples::

    python experiments/peer_architectures.py --out /work/out/peer_architectures
    python experiments/peer_architectures.py --quick --out /tmp/peer

Outputs (``--out``): ``results.csv``, ``timeseries.csv``, ``summary.json`` (with
``extra.unstable_at``, ``extra.table``), ``aoi_vs_n.png``, ``rate_vs_n.png``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sigma_lab import studies

NAME = "peer_architectures"
NODES = (20, 40, 60, 100, 150, 200, 300)
QUICK_NODES = (8, 16)
#: Gazebo-style Lock-Step over DDS (RTPS over UDP; the re-request only restarts the
#: loop at launch, when samples written before discovery matched were not sent).
DDS = ("net.middleware='dds'", "net.transport='datagram'", "net.qos=0",
       "lockstep.retry_timeout=0.25")
#: AirSim-style RPC: TCP straight to the server (a zero-cost relay stands for the
#: switch), msgpack request ~40 B and MultirotorState response ~600 B.
RPC = ("broker.publish_service=0.0", "broker.delivery_service=0.0", "net.qos=0",
       "trigger_payload_bits=320", "payload_bits=4800")
LABELS = (
    studies.MethodSpec("bides_mqtt", "bides"),
    studies.MethodSpec("lockstep_mqtt", "lockstep"),
    studies.MethodSpec("lockstep_dds", "lockstep", DDS),
    studies.MethodSpec("lockstep_dds_noscan", "lockstep", (*DDS, "dds.executor_per_entity=0.0")),
    studies.MethodSpec("rpc", "rpc", RPC),
)
PAPER = {
    "gazebo_aoi_ms": {"60": "12", "200": "62 ± 15"},
    "gazebo_unstable_beyond": "~100 nodes",
    "airsim_aoi_ms": "23-45 (node limit 20-50)",
    "sigma_aoi_ms": "8.7 ± 1.7 (200 nodes)",
    "sigma_latency_ms": "3.5",
}
PINNED = ("dynamics=pointmass", "fidelity.enabled=false")
RATE_FLOOR = 0.5  # unstable below half the nominal frame rate


def overrides(n: int, quick: bool) -> list[str]:
    """The shared scenario at ``n`` nodes."""
    base = [f"nodes={n}", "hosts=10", "f_trig=100.0", "payload_bits=150", "f_render=60.0",
            *PINNED]
    if quick:
        return [*base, "hosts=2", "duration=0.8", "warmup=0.3"]
    return [*base, "duration=6.0", "warmup=1.5"]


def unstable(m: dict[str, float], f_trig: float) -> bool:
    """The study's instability definition (see the module docstring)."""
    return m["trigger_rate_hz"] < RATE_FLOOR * f_trig or m["stalls"] > 0


def figures(study: studies.Study) -> dict[str, Any]:
    """Per label: per N the mean (over seeds) of the reported metrics; unstable N."""
    table: dict[str, dict[int, dict[str, float]]] = {}
    first_unstable: dict[str, int | None] = {}
    for spec in LABELS:
        rows: dict[int, dict[str, float]] = {}
        for v, sc in study.variants.items():
            runs = study.runs(v, spec.label)
            if not runs:
                continue
            cell: dict[str, float] = {}
            for k in ("aoi_mean", "aoi_std", "aoi_p99", "latency_state_mean",
                      "trigger_rate_hz", "stalls", "rerequests", "throughput_mbps"):
                cell[k] = float(study.values(v, spec.label, k).mean())
            cell["rtf"] = cell["trigger_rate_hz"] / sc.f_trig
            cell["unstable"] = float(any(unstable(r.metrics, sc.f_trig) for r in runs))
            rows[sc.nodes] = cell
        table[spec.label] = dict(sorted(rows.items()))
        bad = [n for n, c in table[spec.label].items() if c["unstable"]]
        first_unstable[spec.label] = min(bad) if bad else None
    return {"table": table, "unstable_at": first_unstable,
            "instability": f"trigger_rate < {RATE_FLOOR} x f_trig, or any stall"}


def plots(study: studies.Study, fig: dict[str, Any]) -> None:
    """AoI (mean ± std, p99) and achieved frame rate against N, with the paper's points."""
    plt = studies.plot_setup(study.args.quick)
    out = study.args.out
    table = fig["table"]
    f, axs = plt.subplots(1, 2, figsize=(13, 4.8))
    aoi, rate = {}, {}
    for i, (label, rows) in enumerate(table.items()):
        ns = np.array(list(rows), dtype=float)
        mean = np.array([rows[n]["aoi_mean"] for n in rows])
        std = np.array([rows[n]["aoi_std"] for n in rows])
        c = studies.line_kw(label, i)["color"]
        axs[0].fill_between(ns, mean - std, mean + std, color=c, alpha=0.15, linewidth=0)
        axs[0].plot(ns, [rows[n]["aoi_p99"] for n in rows], linestyle=":", color=c)
        aoi[label] = (ns, mean)
        rate[label] = (ns, np.array([rows[n]["trigger_rate_hz"] for n in rows]))
    studies.plot_lines(axs[0], aoi)
    studies.plot_lines(axs[1], rate)
    axs[0].errorbar([60, 200], [12, 62], yerr=[0, 15], fmt="s", color="k", ms=7, capsize=4,
                    label="paper: Gazebo")
    axs[0].errorbar([200], [8.7], yerr=[1.7], fmt="D", color="g", ms=7, capsize=4,
                    label="paper: SIGMA")
    axs[0].fill_between([20, 50], [23, 23], [45, 45], color="r", alpha=0.15,
                        label="paper: AirSim 23-45 ms, 20-50 nodes")
    axs[0].set_yscale("log")
    axs[0].set_xlabel("physics nodes N")
    axs[0].set_ylabel("AoI (ms; band ± std, dotted p99; log)")
    studies.legend_outside(axs[0], fontsize=7)
    axs[0].set_title("AoI vs swarm size")
    sc = next(iter(study.variants.values()))
    axs[1].axhline(RATE_FLOOR * sc.f_trig, color="k", linestyle="--", linewidth=1,
                   label="instability floor (0.5 × nominal)")
    axs[1].set_xlabel("physics nodes N")
    axs[1].set_ylabel("achieved frame (trigger) rate (Hz)")
    studies.legend_outside(axs[1], fontsize=7)
    axs[1].set_title("achieved frame rate vs swarm size")
    studies.save(f, out, "aoi_vs_n.png")
    f2, ax = plt.subplots(figsize=(6.5, 4.5))
    studies.plot_lines(ax, {
        label: (np.array(list(rows), dtype=float),
                np.array([rows[n]["latency_state_mean"] for n in rows]))
        for label, rows in table.items()
    })
    ax.set_yscale("log")
    ax.set_xlabel("physics nodes N")
    ax.set_ylabel("state latency, publish → server (ms; log)")
    studies.legend_outside(ax, fontsize=7)
    studies.save(f2, out, "rate_vs_n.png")


def text(fig: dict[str, Any]) -> str:
    """The study's table as text."""
    lines = [f"{'label':>20} {'N':>4} {'AoI ms':>16} {'p99':>7} {'lat ms':>7} {'Hz':>6} "
             f"{'stalls':>6} unstable"]
    for label, rows in fig["table"].items():
        for n, c in rows.items():
            aoi = f"{c['aoi_mean']:.1f} ± {c['aoi_std']:.1f}"
            lines.append(f"{label:>20} {n:>4} {aoi:>16} {c['aoi_p99']:>7.1f} "
                         f"{c['latency_state_mean']:>7.2f} {c['trigger_rate_hz']:>6.1f} "
                         f"{c['stalls']:>6.0f} {'yes' if c['unstable'] else 'no'}")
    lines.append("first unstable N: " + ", ".join(
        f"{k}={v}" for k, v in fig["unstable_at"].items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = studies.parse_args(NAME, __doc__, argv, default_seeds="1,2")
    ns = QUICK_NODES if args.quick else NODES
    variants = {f"n{n}": studies.load_scenario(None, overrides(n, args.quick)) for n in ns}
    specs = {v: list(LABELS) for v in variants}
    study = studies.run_study(NAME, args, variants, specs)
    fig = figures(study)
    study.extra = fig
    return studies.finish(study, lambda st: plots(st, fig), PAPER, notes=[text(fig)])

if __name__ == "__main__":
    raise SystemExit(main())
