#!/usr/bin/env python
"""Regenerate ``docs/REPRODUCTION.md`` from the studies' outputs.

Reads ``summary.json`` of every study under the outputs directory (default
``out/``): ``scale_200``, ``scale_1000``, ``latency_tolerance``, ``alignment_cost``,
``faults`` and, if present, ``sweep_nodes``; for each it writes the paper's figure,
ours (tables), the command that produced ours, and why they differ. A study
whose outputs are missing is listed with the command that would produce them.

Examples::

    python experiments/make_report.py                          # out/ -> docs/REPRODUCTION.md
    python experiments/make_report.py --outputs /tmp/q --report /tmp/q/REPORT.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
STUDIES = ("scale_200", "scale_1000", "latency_tolerance", "alignment_cost", "faults")
ORDER = ("none", "lockstep", "lockstep_evict", "hlc", "bides")


# ------------------------------------------------------------------ formatting


def num(x: Any, nd: int = 1) -> str:
    """A number with ``nd`` decimals ("–" for missing or NaN; large numbers unchanged)."""
    if x is None or isinstance(x, str):
        return "–" if x is None else str(x)
    x = float(x)
    if not math.isfinite(x):
        return "–"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{nd}f}"


def table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def labels(var: dict[str, Any]) -> list[str]:
    """Method labels of a variant in canonical order."""
    ms = list(var["methods"])
    return sorted(ms, key=lambda m: ORDER.index(m) if m in ORDER else len(ORDER))


def get(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Mean over seeds of one metric (None if absent)."""
    return var["methods"].get(lab, {}).get(metric)


def sd(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Standard deviation over seeds of one metric (None if absent)."""
    return var.get("std", {}).get(lab, {}).get(metric)


def provenance(s: dict[str, Any]) -> str:
    """Command, seeds and version line of a study."""
    mode = " (**quick mode** — a smoke test, not the study)" if s.get("quick") else ""
    seeds = ",".join(str(x) for x in s.get("seeds", []))
    return (
        f"Command: `{s.get('command', '?')}`{mode} — seeds {seeds}, sigma_des "
        f"{s.get('version', '?')}."
    )


def plots_line(name: str, s: dict[str, Any], outputs: Path) -> str:
    """Where the plots are."""
    ps = s.get("plots", [])
    if not ps:
        return ""
    return "Plots: " + ", ".join(f"`{outputs.name}/{name}/{p}`" for p in ps) + "."


# ------------------------------------------------------------------ sections


def sec_scale_200(s: dict[str, Any]) -> str:
    """The 200-node study."""
    var = s["variants"]["default"]
    sc = var["scenario"]
    rows = []
    for lab in labels(var):
        rows.append(
            [
                lab,
                num(get(var, lab, "latency_state_mean"), 2),
                f"{num(get(var, lab, 'aoi_mean'), 2)} ± {num(get(var, lab, 'aoi_std'), 2)}",
                num(get(var, lab, "aoi_p99"), 1),
                num(get(var, lab, "buffer_bytes_peak") / 1024, 1),
                num(get(var, lab, "throughput_mbps"), 1),
                num(get(var, lab, "snapshot_rate_hz"), 1),
                num(get(var, lab, "trigger_rate_hz"), 1),
                num(get(var, lab, "spread_mean"), 2),
            ]
        )
    t = table(
        [
            "method",
            "state latency (ms)",
            "AoI mean ± std (ms)",
            "AoI p99 (ms)",
            "server buffer peak (KiB)",
            "throughput (Mbps)",
            "snapshots (Hz)",
            "triggers (Hz)",
            "frame spread",
        ],
        rows,
    )
    b = var["methods"].get("bides", {})
    ls = var["methods"].get("lockstep", {})
    h = var["methods"].get("hlc", {})
    return f"""**Paper.** 200 nodes, MQTT QoS 1, 100 Hz, 150-bit states, 2 h: BiDES latency
3.5 ms, AoI 8.7 ± 1.7 ms, < 650 MB per host, rendering > 60 Hz; the lock-step
baseline (Gazebo/FastDDS) AoI 12 ms at 60 nodes → 62 ± 15 ms at 200 nodes, unstable
beyond ~100 nodes.

**Ours.** {sc["nodes"]} nodes on {sc["hosts"]} hosts, QoS {sc["net"]["qos"]} over
the {sc["net"]["transport"]} transport, {sc["f_trig"]:g} Hz, {sc["payload_bits"]}-bit
states, {sc["duration"]:g} s simulated ({sc["warmup"]:g} s warm-up excluded), rendering
at {sc["f_render"]:g} Hz. Mean over seeds; "±" is the standard deviation of the AoI
samples (render tick × node).

{t}

**Why they differ.**

* *Kind — reproduced:* BiDES shows one frame for the whole swarm (spread 0) with AoI
  {num(b.get("aoi_mean"), 1)} ± {num(b.get("aoi_std"), 1)} ms and keeps the full
  {num(b.get("snapshot_rate_hz"), 0)} Hz snapshot rate; HLC waits for causal stability
  and pays for it ({num(h.get("aoi_mean"), 1)} ms). Our AoI is of the same order as
  the paper's 8.7 ± 1.7 ms; render ticks sample it
  {num((sc.get("render_phase", 0.0) - sc.get("align_phase", 0.0)) % 1.0, 2)} of an alignment
  period after each alignment tick (time average {num(b.get("aoi_time_avg"), 1)} ms; the
  sawtooth's bottom lies {num(500.0 / float(sc["f_align"]), 1)} ms below the time average;
  docs/MODEL.md, Metrics).
* *Lock-Step does not collapse here.* In our model Lock-Step reaches
  {num(ls.get("aoi_mean"), 1)} ms at {sc["nodes"]} nodes, not the paper's 62 ± 15 ms: the
  paper's baseline is a different system (Gazebo with FastDDS; Lock-Step over our DDS
  model is in the peer-architectures section); over MQTT our barrier costs one round
  trip through a lightly loaded broker on a LAN with no loss and 0.8 ms steps, so
  the barrier completes well within the 10 ms frame. Lock-Step degrades in our model
  when rounds get slow — loss, stragglers, crashes (see the latency-tolerance and
  fault studies); on a saturated broker (1000 nodes) its blocking even helps, pacing
  the triggers to what the broker can serve.
* *Latency.* Our state latency is the model's publish → server delivery (two LAN
  hops of 0.25 ms, serialization, broker service) — the paper's 3.5 ms includes
  the real software stack (Python MQTT clients, OS scheduling) that we represent
  only by the configured constants.
* *Memory.* The paper's < 650 MB is the whole process per physics host; ours is
  the alignment server's state buffer only (BiDES: k = 30 states per node), a few
  hundred KiB — the part that depends on the method.
* *Duration.* {sc["duration"]:g} s simulated instead of 2 h: every metric here is
  stationary after the warm-up (see `aoi_over_time.png`)."""


def sec_scale_1000(s: dict[str, Any]) -> str:
    """The 1000-node study."""
    var = s["variants"]["default"]
    sc = var["scenario"]
    cap = s.get("extra", {}).get("broker", {})
    rows = []
    for v_name, v in s["variants"].items():
        for lab in labels(v):
            rows.append(
                [
                    lab if v_name == "default" else f"{lab} ({v_name.replace('_', ' ')})",
                    num(get(v, lab, "throughput_mbps"), 1),
                    f"{num(get(v, lab, 'aoi_mean'), 1)} ± {num(get(v, lab, 'aoi_std'), 1)}",
                    num(get(v, lab, "latency_state_mean"), 1),
                    num(100 * (get(v, lab, "broker_util") or math.nan), 0),
                    num(get(v, lab, "trigger_rate_hz"), 1),
                    num(get(v, lab, "f_trig_settled_hz"), 1),
                    num(get(v, lab, "snapshot_rate_hz"), 1),
                ]
            )
    t = table(
        [
            "method",
            "throughput (Mbps)",
            "AoI mean ± std (ms)",
            "state latency (ms)",
            "broker load (%)",
            "achieved triggers (Hz)",
            "f_trig in force, last quarter (Hz)",
            "snapshots (Hz)",
        ],
        rows,
    )
    c = cap.get("default", {})
    cf = cap.get("fast_broker", {})
    b = var["methods"].get("bides", {})
    n = var["methods"].get("none", {})
    ls = var["methods"].get("lockstep", {})
    q = s.get("extra", {}).get("bides_f_trig_last_quarter", {})
    pub = sc["broker"]["publish_service"]
    dlv = sc["broker"]["delivery_service"]
    pub_us = 1e6 * (pub["value"] if pub["dist"] == "constant" else pub["mean"])
    dlv_us = 1e6 * (dlv["value"] if dlv["dist"] == "constant" else dlv["mean"])
    return f"""**Paper.** 1000 nodes: 208.4 Mbps, AoI 19 ± 3.7 ms, the adaptive trigger rate
settles at 50 Hz.

**Ours.** {sc["nodes"]} nodes, {sc["nodes"] // sc["hosts"]} per host on {sc["hosts"]}
hosts (the paper's 20 aircraft per PC; the paper does not say how its 1000 nodes were
placed), QoS {sc["net"]["qos"]}, nominal {sc["f_trig"]:g} Hz, {sc["duration"]:g} s
simulated. Broker service: {pub_us:g} µs per inbound PUBLISH, {dlv_us:g} µs per
delivery (the `fast_broker` row: 4× faster).

{t}

Broker load: one frame costs the broker {num(1000 * c.get("broker_s_per_frame", math.nan), 2)}
ms (a trigger fanned out to {sc["nodes"]} nodes plus {sc["nodes"]} states), commands
add {num(100 * c.get("command_load", math.nan), 0)} % — offered load at the nominal
rate {num(100 * c.get("offered_load_at_nominal", math.nan), 0)} %, so the broker can
sustain at most ≈ {num(c.get("max_trigger_hz"), 0)} Hz of triggers (4× faster broker:
≈ {num(cf.get("max_trigger_hz"), 0)} Hz). BiDES's trigger rate over the last quarter of
the run: mean {num(q.get("mean"), 1)} Hz, range {num(q.get("min"), 1)}–{num(q.get("max"), 1)} Hz.

**Why they differ.**

* *Throughput.* Ours counts every packet on every link direction (node → broker and
  broker → server for states, server → broker → node for triggers and commands,
  PUBACKs, with MQTT, TCP/IP and Ethernet headers) — {num(n.get("throughput_mbps"), 0)}
  Mbps without alignment at the full rate. A 150-bit state becomes a ~100-byte frame on
  the wire and is counted on two links; the paper's 208.4 Mbps is probably measured
  at one point (the broker's NIC or the server) and at the settled 50 Hz; at a
  lower achieved trigger rate our total scales down with it (BiDES row).
* *The adaptive rate.* The paper's rate settles at 50 Hz; ours is set by where our
  broker saturates. With the default service times the broker is overloaded at
  100 Hz, states queue, the alignment lag exceeds `lag_high` and BiDES lowers
  `f_trig` until the queue drains, then raises it again while the lag stays low —
  a limit cycle around the broker's capacity rather than one settled value (see
  `trigger_rate.png`). With the 4× faster broker the rate stays at 100 Hz. The
  paper's 50 Hz is a statement about its broker and network, whose service times it
  does not give; ours are parameters (`broker.publish_service`,
  `broker.delivery_service`).
* *Lock-Step paces itself.* Its barrier issues the next trigger only when the frame
  is complete, so it settles at what the broker can serve
  ({num(ls.get("trigger_rate_hz"), 0)} Hz) without a controller, and keeps the broker
  queue short: AoI {num(ls.get("aoi_mean"), 1)} ± {num(ls.get("aoi_std"), 1)} ms, the
  closest of our methods to the paper's 19 ± 3.7 ms. On a lossless LAN with uniform
  nodes its blocking costs nothing; it loses when rounds get slow (loss, stragglers,
  crashes — see the latency-tolerance and fault studies).
* *AoI.* BiDES's {num(b.get("aoi_mean"), 1)} ± {num(b.get("aoi_std"), 1)} ms (paper 19
  ± 3.7 ms) includes the broker queueing of a near-saturated broker; AoI rises and
  falls with the limit cycle. Without alignment (`none`) the broker queue grows at
  the full 100 Hz and AoI with it."""


def sec_latency(s: dict[str, Any]) -> str:
    """The latency-tolerance study."""
    parts = []
    sc = None
    for v_name, var in s["variants"].items():
        sc = var["scenario"]
        rows = []
        for lab in labels(var):
            rows.append(
                [
                    lab,
                    f"{num(get(var, lab, 'aoi_mean'), 1)} ± {num(get(var, lab, 'aoi_std'), 1)}",
                    num(get(var, lab, "aoi_p99"), 0),
                    num(get(var, lab, "latency_state_mean"), 1),
                    f"{num(get(var, lab, 'displacement_mean_ms'), 0)} / "
                    f"{num(get(var, lab, 'displacement_max_ms'), 0)}",
                    f"{num(get(var, lab, 'pos_err_mean'), 3)} / "
                    f"{num(get(var, lab, 'pos_err_max'), 2)}",
                    num(get(var, lab, "snapshot_rate_hz"), 1),
                    num(get(var, lab, "aligned_rate_hz"), 1),
                    num(get(var, lab, "trigger_rate_hz"), 1),
                    f"{num(get(var, lab, 'filled_frac'), 2)} / "
                    f"{num(get(var, lab, 'extrapolated_frac'), 2)}",
                ]
            )
        parts.append(
            f"*{v_name} transport:*\n\n"
            + table(
                [
                    "method",
                    "AoI mean ± std (ms)",
                    "AoI p99 (ms)",
                    "state latency (ms)",
                    "displacement mean / max (ms)",
                    "position error mean / max (m)",
                    "snapshots (Hz)",
                    "aligned frames/s",
                    "triggers (Hz)",
                    "filled / extrapolated",
                ],
                rows,
            )
        )
    assert sc is not None
    d = s["variants"].get("datagram", next(iter(s["variants"].values())))
    st = s["variants"].get("stream")
    ratio = (get(d, "bides", "aoi_mean") or math.nan) / (get(d, "hlc", "aoi_mean") or math.nan)
    lat = sc["net"]["host_link"]["latency"]
    stream_txt = ""
    if st is not None:
        stream_txt = f"""
* *Stream (TCP-like) transport.* Lost segments are resent after an RTO
  ({sc["net"]["rto"]:g} s, doubling per retry) and hold back everything behind them on
  the connection. At 30 % loss that is most of the time: state latency rises to
  {num(get(st, "none", "latency_state_mean"), 0)} ms, AoI to seconds for every method,
  the shown swarm spreads over hundreds of frames without alignment, Lock-Step nearly
  stops ({num(get(st, "lockstep", "trigger_rate_hz"), 1)} triggers/s), and BiDES's
  lag-driven adaptation pulls the trigger rate down towards its floor
  ({num(get(st, "bides", "f_trig_settled_hz"), 0)} Hz at the end) while excluding the
  nodes held back by head-of-line blocking (extrapolated fraction
  {num(get(st, "bides", "extrapolated_frac"), 2)}). Reliable in-order delivery is the
  wrong transport for state streams on a lossy link: a fresh state is worth more than a
  complete history, which is the datagram (or QoS 0 + newest-wins) design the paper's
  latency-tolerance claim presupposes."""
    return f"""**Paper.** 10 nodes, 30 % packet loss, 30 ± 10 ms delay, alignment at 30 Hz,
physics at 100 Hz: without alignment the swarm flickers (30–90 ms displacement); HLC
mean AoI ≈ 70 ms; BiDES ≈ 38 ms at a stable 20 Hz.

**Ours.** `scenarios/latency_tolerance.toml`: {sc["nodes"]} nodes, one per host,
{100 * sc["net"]["host_link"]["loss"]["p"]:g} % Bernoulli loss and normal
{1000 * lat["mean"]:g} ± {1000 * lat["std"]:g} ms one-way delay on every physics
host's link (both directions), triggers at {sc["f_trig"]:g} Hz, alignment and
rendering at {sc["f_align"]:g} Hz, {sc["duration"]:g} s, {sc["dynamics"]} dynamics.
*Displacement* is the frame spread of the shown snapshot expressed as time (spread ×
frame period); *position error* is the distance between a shown state and the node's
true position at the snapshot's frame. "Filled / extrapolated" are the fractions of
shown states that BiDES filled across a hole or extrapolated for a lagging node.

{chr(10).join(p + chr(10) for p in parts)}
**Why they differ.**

* *Kind — reproduced (datagram):* without alignment the shown swarm mixes frames
  {num(get(d, "none", "displacement_mean_ms"), 0)} ms apart on average (max
  {num(get(d, "none", "displacement_max_ms"), 0)} ms), the paper's 30–90 ms flicker;
  HLC waits for causal stability behind the slowest, lossiest link and has the
  highest AoI of the free-running methods ({num(get(d, "hlc", "aoi_mean"), 0)} ms);
  BiDES has lower AoI ({num(get(d, "bides", "aoi_mean"), 0)} ms, ratio BiDES/HLC
  {num(ratio, 2)} vs the paper's 38/70 = 0.54) and a stable rendered rate
  ({num(get(d, "bides", "snapshot_rate_hz"), 1)} new snapshots per second at a
  {sc["f_render"]:g} Hz render rate) with near-zero position error. Lock-Step
  stalls: every lost trigger or state costs a retry timeout
  ({sc["lockstep"]["retry_timeout"]:g} s), so it advances only
  {num(get(d, "lockstep", "trigger_rate_hz"), 1)} frames/s.
* *Size.* Our AoIs are larger than the paper's. A state is ~30 ms old when it reaches
  the server (the impaired host link; the server's own link is a fast LAN link), waits
  ~17 ms on average for the next 30 Hz alignment/render tick, and a lost state leaves
  the previous one on screen one more frame. That puts *no alignment* — which always
  shows the newest state received and is therefore a lower bound on AoI for every
  method — at {num(get(d, "none", "aoi_mean"), 0)} ms, above the paper's BiDES 38 ms. The
  paper does not say whether its 30 ± 10 ms is one-way, per hop or a round trip, nor
  how it measures AoI; with half the delay our figures would land near the paper's.
* *BiDES's exclusions.* With Θ_lag = 3 frames (30 ms at 100 Hz) and 30 % loss a
  node's newest frame often lags by more than Θ_lag, so BiDES extrapolates a third of
  the shown states; the position error stays small because the aircraft's motion over
  a few frames is close to linear. Its spread is therefore not 0 here (excluded
  nodes keep their own frame); without exclusions it is 0 by construction.
* *BiDES's rate.* The paper's BiDES runs "at a stable 20 Hz"; ours keeps the trigger
  rate at 100 Hz on the datagram transport (its lag stays under `lag_high`) and shows
  a new aligned snapshot at almost every 30 Hz alignment tick.
{stream_txt}"""


def sec_cost(s: dict[str, Any]) -> str:
    """The alignment-cost study."""
    cost = s["cost"]
    ns = sorted(cost, key=int)
    rows = []
    for n in ns:
        c = cost[n]
        row = [f"{int(n):,}"]
        for m in ("bides", "hlc", "lockstep"):
            x = c.get(m, {})
            row.append(f"{num(x.get('align_median_ms'), 3)} / {num(x.get('align_p95_ms'), 3)}")
            row.append(num(x.get("ingest_median_ms"), 2))
        rows.append(row)
    t = table(
        [
            "n",
            "BiDES Algorithm 1 median / p95 (ms)",
            "BiDES inserts per frame (ms)",
            "HLC tick median / p95 (ms)",
            "HLC pushes per tick (ms)",
            "Lock-Step tick median / p95 (ms)",
            "Lock-Step arrivals per frame (ms)",
        ],
        rows,
    )
    p = s.get("params", {})
    mach = s.get("machine", {})
    b1000 = cost.get("1000", {}).get("bides", {}).get("align_median_ms")
    period = 1000.0 / float(p.get("f_align", 60.0))
    ok = [int(n) for n in ns if (cost[n].get("bides", {}).get("align_median_ms") or 1e9) < period]
    fits = f"{max(ok):,}" if ok else "none of the tested n"
    big = ns[-1]
    b_big = cost[big].get("bides", {}).get("align_median_ms")
    return f"""**Paper.** Algorithm 1 with n = 1000 nodes and k = 30: < 8 ms.

**Ours.** `sigma_des.events.align.ring.align` over `RingBuffers` with k = {p.get("k")},
filled as a running swarm leaves them (most nodes 0–2 frames behind the newest, some
3–5, ~2 % beyond Θ_lag = {p.get("theta_lag")} and excluded, {100 * p.get("hole_p", 0):g} %
of buffered frames lost), hole filling and lag exclusion on; timed with
`time.perf_counter` (median and p95 over repeats) on {mach.get("processor", "?")},
Python {mach.get("python", "?")}. For comparison, the per-tick cost of the HLC and
Lock-Step aligners of the engine, and the cost of receiving the states (one Python
call per state) separately.

{t}

**Why they differ.** At n = 1000 Algorithm 1 takes {num(b1000, 2)} ms here — within
the paper's < 8 ms. It is vectorised over nodes (numpy over the n × k ring), so it grows
roughly linearly in n·k ({num(b_big, 1)} ms at n = {int(big):,}); it fits in one alignment
period ({num(period, 1)} ms at {num(p.get("f_align"), 0)} Hz) up to n = {fits}. The paper's
figure depends on its implementation and machine, which it does not describe. In our
implementation the larger costs sit elsewhere: receiving the states is one Python call
per state (ring insert, HLC heap push, barrier bookkeeping) and dominates at large n;
Lock-Step's arrival cost grows faster than n because its completeness check scans all
live nodes on every arrival (O(n²) per frame); and HLC's tick releases every stable
state one by one in Python (heap pop, unpacking, row copies), so it grows with n × the
states per tick and is the most expensive alignment step from n = 100 on. Timings vary
with machine load (p95 especially): these are single runs on a shared, busy 2-core
machine."""


def sec_faults(s: dict[str, Any]) -> str:
    """The fault study."""
    ex = s.get("extra", {})
    win = ex.get("windows", {})
    fw = ex.get("fault_window_s", {})
    tgt = ex.get("target", {})
    parts = []
    sc = None
    for v_name, var in s["variants"].items():
        sc = var["scenario"]
        rows = []
        for lab in labels(var):
            w = win.get(v_name, {}).get(lab, {})
            rows.append(
                [
                    lab,
                    f"{num(w.get('aoi_before_ms'), 0)} / {num(w.get('aoi_during_ms'), 0)} / "
                    f"{num(w.get('aoi_after_ms'), 0)}",
                    f"{num(w.get('aligned_rate_before_hz'), 0)} / "
                    f"{num(w.get('aligned_rate_during_hz'), 0)} / "
                    f"{num(w.get('aligned_rate_after_hz'), 0)}",
                    num(get(var, lab, "stall_time_s"), 2),
                    num(get(var, lab, "evicted"), 1),
                    num(get(var, lab, "extrapolated_frac"), 3),
                    num(w.get("recovery_s"), 2),
                ]
            )
        a, b = fw.get(v_name, (math.nan, math.nan))
        parts.append(
            f"*{v_name}* (fault window {num(a, 1)}–{num(b, 1)} s):\n\n"
            + table(
                [
                    "method",
                    "AoI before / during / after (ms)",
                    "aligned frames/s before / during / after",
                    "stalled (s)",
                    "evicted",
                    "extrapolated",
                    "recovery (s)",
                ],
                rows,
            )
        )
    assert sc is not None
    return f"""**Paper.** No fault-injection figure; this study checks the paper's qualitative
claims: Lock-Step blocks on its slowest node, HLC waits for stability, BiDES excludes
laggards optimistically and catches up.

**Ours.** {sc["nodes"]} nodes on {sc["hosts"]} hosts, {sc["f_trig"]:g} Hz, QoS
{sc["net"]["qos"]} over the {sc["net"]["transport"]} transport, physics step 3 ± 0.5 ms,
{sc["duration"]:g} s. Faults: node {tgt.get("node")} crashes; node {tgt.get("node")} runs 5×
slower (15 ms per 10 ms frame: it cannot keep up); host {tgt.get("host")}'s link gets 50 ms
extra delay and 30 % extra loss. `lockstep_evict` = Lock-Step with
`lockstep.eviction_timeout = {tgt.get("eviction_timeout_s")}` s. "After" starts 0.5 s after
the window; recovery = time after the window until the mean AoI is back within 1.5× its
pre-fault median. Means over seeds.

{chr(10).join(p + chr(10) for p in parts)}
**What each method does.**

* *Crash.* Lock-Step without eviction stops for good at the crash (aligned rate 0,
  stalled to the end); with eviction it stalls {tgt.get("eviction_timeout_s")} s, evicts
  the node and carries on without it. HLC stops releasing states until the liveness
  timeout (0.5 s) declares the node dead, then resumes. BiDES never stops: the dead
  node falls more than Θ_lag frames behind and is excluded (its last state
  extrapolated and flagged), the others keep their full rate. Without alignment the
  dead node's stale state is simply shown forever (its AoI grows without bound, which
  is what the AoI max shows for every method that keeps showing it).
* *Straggler.* Lock-Step runs at the straggler's pace for the whole window (eviction
  does not fire: the node is slow, not silent). HLC's stability bound is held back by
  the straggler's stamps, so the whole swarm's AoI rises and releases come in bursts.
  BiDES excludes the straggler and keeps the others at full rate.
* *Degraded host.* Lost packets on the stream transport are resent after RTO with
  back-off and block their connections, so the affected host's states arrive in
  bursts. Lock-Step stalls on every hole; with eviction it drops the affected host's
  nodes during the window, and each rejoins once it delivers the frame the barrier
  is waiting for (after the window, when its connection has drained), so
  `lockstep_evict` recovers to the full swarm. HLC waits for the slow host. BiDES
  excludes the late nodes during the window, keeps showing the other hosts' nodes at the
  full rate and takes the late ones back when they catch up; the affected nodes' own
  states are still late (head-of-line blocking drains for a while after the window), so
  the swarm's mean AoI rises for every method that keeps showing them.

The plotted and tabulated AoI is the mean over *all* nodes, the faulty one included: a
crashed node's last state only gets older (its age dominates the mean and the maximum
for every method that keeps showing it — all but Lock-Step without eviction, which
shows nothing new at all)."""


def sec_sweep(s: dict[str, Any]) -> str:
    """The node-count sweep (written by ``experiments/sweep_nodes.py``)."""
    figs = s.get("figures", {})
    out = [
        "**Paper.** Lock-step AoI 12 ms at 60 nodes → 62 ± 15 ms at 200, unstable beyond "
        "~100 nodes; BiDES AoI 8.7 ms at 200 and 19 ms at 1000 nodes."
    ]
    meta = []
    for k in ("nodes", "methods", "seeds", "duration_s", "runs"):
        if k in s:
            meta.append(f"{k} = {s[k]}")
    out.append("**Ours.** " + ", ".join(meta) + ".")
    if isinstance(figs, dict) and figs:
        # figures: {method: {N: {metric: {mean, ci95, n}}}}
        methods = sorted(figs, key=lambda m: ORDER.index(m) if m in ORDER else len(ORDER))
        ns = sorted({n for m in methods for n in figs[m]}, key=lambda x: float(x))
        metrics = sorted({k for m in methods for d in figs[m].values() for k in d})
        for metric in metrics:
            rows = []
            for n in ns:
                row = [str(n)]
                for m in methods:
                    cell = figs[m].get(n, {}).get(metric)
                    if isinstance(cell, dict):
                        row.append(f"{num(cell.get('mean'), 2)} ± {num(cell.get('ci95'), 2)}")
                    else:
                        row.append(num(cell, 2))
                rows.append(row)
            out.append(
                f"*{metric}* (mean ± 95 % CI over seeds):\n\n" + table(["N", *methods], rows)
            )
    if "lockstep_degrades_at" in s:
        where = s["lockstep_degrades_at"]
        rule = s.get("degrade_rule", "")
        out.append(
            f"Lock-Step degrades ({rule}): "
            + (f"N = {where}." if where is not None else "not within the grid.")
        )
    where = s.get("lockstep_degrades_at")
    verdict = (
        f"in our model it degrades from N = {where} on"
        if where is not None
        else "in our model it does not degrade within the grid"
    )
    out.append(
        "**Why they differ.** The sweep uses the same model as the scale studies (20 nodes "
        "per host, LAN latency, the default broker). Lock-Step's barrier costs one broker "
        "round trip per frame, which only becomes expensive when rounds get slow (a "
        f"saturating broker, loss, stragglers): {verdict}, whereas the paper's "
        "Gazebo/FastDDS baseline is unstable beyond ~100 nodes for reasons in its own "
        "transport stack (Lock-Step over our DDS model: the peer-architectures section)."
    )
    return "\n\n".join(out)


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
    head = f"""# Reproduction of the paper's studies

*Generated by `python experiments/make_report.py` from the studies' outputs in
`{outputs.name}/`; do not edit by hand — rerun the studies and this script.*

The paper is Zhang et al., "SIGMA: An Agent-Based Modeling UAV Swarm Simulator for
Swarm Intelligence Algorithms"; its reference figures are listed in DESIGN §7. We
reproduce each study *in kind* with sigma_des's discrete-event model (see
[`MODEL.md`](MODEL.md)): same swarm sizes, rates, payloads, loss and delay where the
paper gives them, our documented defaults where it does not. All four methods run on
identical random draws; tables show means over seeds.

To regenerate everything (full modes; about 12 minutes on 2 cores with the cohort
engine — 6 of them the 140-run node sweep — `--jobs 2` to
parallelise seeds):

```bash
python experiments/scale_200.py
python experiments/scale_1000.py
python experiments/latency_tolerance.py
python experiments/alignment_cost.py
python experiments/faults.py
python experiments/sweep_nodes.py        # optional, Dask
python experiments/make_report.py
```

Every study writes `summary.json`, a tidy `results.csv` (one row per variant × seed
× method × metric, with `seed`, `config_hash` and `version`), `timeseries.csv` and PNG
plots into `{outputs.name}/<study>/`; `--quick` runs a seconds-long smoke version
(used by the tests), `--seeds 1,2,3` picks seeds, `--out DIR` the output directory.
"""
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
        "--report", type=Path, default=ROOT / "docs" / "REPRODUCTION.md", help="report to write"
    )
    a = p.parse_args(argv)
    text = build(a.outputs)
    a.report.parent.mkdir(parents=True, exist_ok=True)
    a.report.write_text(text)
    found = [n for n in SECTIONS if (a.outputs / n / "summary.json").exists()]
    print(f"wrote {a.report} ({len(found)} of {len(SECTIONS)} studies: {', '.join(found)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
