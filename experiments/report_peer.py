"""The ``peer_architectures`` section of ``lab/record/REPRODUCTION.md`` (make_report.py).

``section(outputs)`` reads ``<outputs>/peer_architectures/summary.json`` (written by
``experiments/peer_architectures.py``) and returns Markdown: per architecture and
swarm size the AoI, p99, latency, frame rate, stalls and stability, the paper's
Fig. 16 / Table IV figures beside ours, what the data say about the paper's shape,
and why the figures differ.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

TITLE = "Peer architectures: SIGMA vs Gazebo-style DDS Lock-Step vs AirSim-style RPC"
NAME = "peer_architectures"
_PAPER = {
    "lockstep_dds": "Gazebo: 12 ms at 60, 62 ± 15 ms at 200, unstable beyond ~100",
    "rpc": "AirSim: 23–45 ms, node limit 20–50",
    "bides_mqtt": "SIGMA: 8.7 ± 1.7 ms at 200 (latency 3.5 ms)",
}


def _f(x: Any, nd: int = 1) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{nd}f}"


def _n(x: Any) -> str:
    return "none in the grid" if x is None else str(x)


def _cell(table: dict[str, Any], label: str, n: int) -> dict[str, float] | None:
    return table.get(label, {}).get(str(n))


def _shape(table: dict[str, Any], unstable: dict[str, Any]) -> list[str]:
    """What the data say about each of the paper's claims (computed, not asserted)."""
    out: list[str] = []
    d60, d200 = _cell(table, "lockstep_dds", 60), _cell(table, "lockstep_dds", 200)
    if d60 and d200:
        u = unstable.get("lockstep_dds")
        out.append(
            f"* **Lock-Step over DDS** (Gazebo-style): AoI {_f(d60['aoi_mean'])} ms at 60 nodes "
            f"(paper 12) and {_f(d200['aoi_mean'])} ± {_f(d200['aoi_std'])} ms at 200 (paper "
            f"62 ± 15); first unstable N in our grid: {_n(u)} "
            "(paper: beyond ~100). The growth is "
            + ("super-linear" if d200["aoi_mean"] > 200 / 60 * d60["aoi_mean"] else "sub-linear")
            + " in N.")
    ns = sorted(int(n) for n in table.get("lockstep_dds_noscan", {}))
    if ns and d200:
        e = _cell(table, "lockstep_dds_noscan", 200)
        if e:
            out.append(
                f"* Without the executor's per-message entity scan (`lockstep_dds_noscan`) the "
                f"same DDS Lock-Step gives {_f(e['aoi_mean'])} ms at 200: the O(N) scan per "
                "received state at the server (O(N²) per step) is what drives the degradation; "
                "unicast fan-out and per-message middleware costs alone grow linearly.")
    rpc = table.get("rpc", {})
    if rpc:
        lim = unstable.get("rpc")
        stable = [int(n) for n, c in rpc.items() if not c["unstable"]]
        top = max(stable) if stable else None
        c = rpc.get(str(top)) if top is not None else None
        out.append(
            f"* **RPC** (AirSim-style): largest stable N in our grid {top if top else 'none'}"
            + (f" with AoI {_f(c['aoi_mean'])} ± {_f(c['aoi_std'])} ms" if c else "")
            + f"; first unstable N {_n(lim)} (paper: 23–45 ms at a node limit of 20–50).")
    b = table.get("bides_mqtt", {})
    if b:
        aois = [c["aoi_mean"] for c in b.values()]
        out.append(
            f"* **BiDES over MQTT**: AoI {_f(min(aois))}–{_f(max(aois))} ms over N = "
            f"{min(int(n) for n in b)}…{max(int(n) for n in b)}, first unstable N "
            f"{_n(unstable.get('bides_mqtt'))} (paper: 8.7 ± 1.7 ms at 200, flat).")
    return out


def section(outputs: Path) -> str:
    """Markdown for the study (a 'Not run' note when its outputs are missing)."""
    path = Path(outputs) / NAME / "summary.json"
    if not path.exists():
        return (f"## {TITLE}\n\nNot run: `python experiments/{NAME}.py` writes "
                f"`{Path(outputs).name}/{NAME}/summary.json`.\n")
    s = json.loads(path.read_text())
    extra = s["extra"]
    table, unstable = extra["table"], extra["unstable_at"]
    out = [f"## {TITLE}", ""]
    out.append(
        "The paper's headline comparison (Fig. 16, Tables I/IV) on one workload and identical "
        "draws: N physics nodes on 10 hosts, 100 Hz nominal, 150-bit states. Lock-Step over "
        "DDS models Gazebo on ROS 2 / Fast DDS (`scenarios/gazebo_lockstep_dds.toml`), RPC "
        "models AirSim (`scenarios/airsim_rpc.toml`); every parameter and its source is in "
        "`sigma_des/net/spec.py` (DDS), `sigma_des/events/align/spec.py` (RPC) and "
        "[`MODEL.md`](MODEL.md). *Unstable*: "
        f"{extra['instability']} (a gap > 100 ms without a new snapshot). Means over seeds "
        f"{s['seeds']}{' (quick mode)' if s.get('quick') else ''}.")
    out += ["", "| architecture | N | AoI mean ± std (ms) | AoI p99 | state latency (ms) | "
            "frame rate (Hz) | stalls | unstable | paper |",
            "|---|---|---|---|---|---|---|---|---|"]
    for label, rows in table.items():
        for n, c in sorted(rows.items(), key=lambda kv: int(kv[0])):
            out.append(
                f"| {label} | {n} | {_f(c['aoi_mean'])} ± {_f(c['aoi_std'])} | "
                f"{_f(c['aoi_p99'])} | {_f(c['latency_state_mean'], 2)} | "
                f"{_f(c['trigger_rate_hz'])} | {c['stalls']:.0f} | "
                f"{'yes' if c['unstable'] else 'no'} | {_PAPER.get(label, '')} |")
    out += ["", "What the data say about the paper's shape:", "", *_shape(table, unstable)]
    excess = []
    for n in (60, 200):
        dn, bn = _cell(table, "lockstep_dds", n), _cell(table, "bides_mqtt", n)
        if dn and bn:
            excess.append(f"{_f(dn['aoi_mean'] - bn['aoi_mean'])} ms at {n}")
    sc = next(iter(s["variants"].values()))["scenario"]
    d, r = sc["dds"], sc["rpc"]
    us = 1e6
    out += ["", "Why the figures differ (and what is modelled):", "",
            f"* DDS costs are per-message CPU estimates (writer {d['writer_cost']['value'] * us:g} "
            f"µs per send, reader {d['reader_cost']['value'] * us:g} µs, "
            f"{d['executor_per_entity'] * us:g} µs per executor entity per dispatch, derived "
            "from a published executor profile), not measurements of the paper's machines; "
            "the DDS curve scales with them. Loss is zero here, so RTPS repairs "
            f"(HEARTBEAT/ACKNACK every {d['heartbeat_period']:g} s) and discovery (SPDP every "
            f"{d['spdp_period']:g} s, SEDP all-to-all) only add start-up and background traffic.",
            "* Every AoI here includes where the render ticks sample the AoI sawtooth "
            f"(render ticks at (j + {sc.get('render_phase', 0)}) / f_render; see the 200-node "
            "section), the same offset for every "
            "architecture; Lock-Step over DDS exceeds BiDES over MQTT by "
            + (", ".join(excess) if excess else "–") + ".",
            "* Gazebo's own per-step work (physics of every model in one server, sensor "
            "plugins) is not modelled: its server only does the barrier and the messaging.",
            f"* RPC's game-thread call cost ({r['call_time']['value'] * 1e3:g} ms) and render "
            f"time ({r['render_time']['mean'] * 1e3:g} ± {r['render_time']['std'] * 1e3:g} ms + "
            f"{r['render_per_vehicle'] * 1e3:g} ms per vehicle) are estimates for an Unreal "
            "scene; AirSim's memory (> 2 GB) is not modelled.",
            "* Lock-Step over MQTT does not collapse: one broker round trip and no per-reader "
            "sends or executor scans (see the node-count sweep)."]
    out.append("")
    return "\n".join(out)
