"""The output-file reference page, generated from the code that writes the files.

``results.csv`` and ``wall.csv`` columns (``sigma_des.api.TIDY_COLUMNS``), every metric
with its unit (``METRIC_UNITS``, ``WALL_METRICS``), the ``summary.json`` keys
(``Results.summary``) and the MCAP topics with their JSON schemas
(``sigma_des.record.schemas``). A metric the code reports and this module does not
describe stops the build.
"""

from __future__ import annotations

from typing import Any

from sigma_docs_keys import myst_inline

from sigma_des.api import TIDY_COLUMNS, Results
from sigma_des.config import Scenario
from sigma_des.metrics.collector import METRIC_UNITS, WALL_METRICS
from sigma_des.record.schemas import KINDS, SCHEMAS

__all__ = ["METRIC_DOCS", "outputs_page"]

#: What each metric measures (docs/MODEL.md, "Metrics", says how).
METRIC_DOCS: dict[str, str] = {
    **{f"aoi_{s}": f"Age of Information of the shown states, {w} over render ticks × nodes"
       for s, w in (("mean", "mean"), ("std", "standard deviation"), ("p50", "median"),
                    ("p95", "95th percentile"), ("p99", "99th percentile"),
                    ("max", "maximum"))},
    "aoi_time_avg": "time average of AoI (exact area under the sawtooth / node-time)",
    "aoi_peak_mean": "peak AoI: AoI just before each update, averaged",
    **{f"latency_{k}_{s}": f"{k} latency, publish to first application-level delivery, "
       f"{'mean' if s == 'mean' else '99th percentile'}"
       for k in ("state", "trigger", "command") for s in ("mean", "p99")},
    "throughput_mbps": "wire bits of every packet on every link direction (MQTT + TCP/IP + "
                       "Ethernet) over the window, summed over links",
    "throughput_max_link_mbps": "the busiest link direction's wire rate",
    "packets_per_s": "packets on all links per second",
    "deliveries_per_s": "first deliveries of application messages per second (a trigger "
                        "broadcast to n nodes is n deliveries)",
    "trigger_rate_hz": "triggers issued per second of the window",
    "f_trig_final_hz": "trigger rate at the end of the run (BiDES adapts it)",
    "f_trig_min_hz": "lowest trigger rate during the run",
    "snapshot_rate_hz": "alignment ticks per second at which the shown snapshot advanced",
    "snapshot_interval_std_ms": "standard deviation of the interval between new snapshots",
    "stalls": "gaps without a new snapshot longer than `stall_threshold`",
    "stall_time_s": "total time spent in stalls",
    "spread_mean": "max − min frame of the shown states, mean over alignment ticks",
    "spread_max": "max − min frame of the shown states, maximum",
    "pos_err_mean": "distance between a shown position and the node's true position at the "
                    "snapshot's reference frame, mean",
    "pos_err_max": "the same, maximum",
    "filled_frac": "share of shown slots BiDES filled from neighbouring frames",
    "extrapolated_frac": "share of shown slots BiDES extrapolated",
    "off_frame_frac": "share of shown slots whose frame differs from the reference frame",
    "duplicates": "deliveries after a message's first (a resent copy that arrived again)",
    "retransmissions": "packets sent again (stream RTO or QoS 1 timeout)",
    "gave_up": "packets given up after `net.max_retries` resends (or a DDS GAP)",
    "broker_util": "busy fraction of the broker's thread",
    "broker_max_wait_ms": "longest wait of a PUBLISH in the broker's queue",
    "server_cpu_util": "CPU stage: busy fraction of the server's process",
    "server_cpu_max_wait_ms": "CPU stage: longest wait of a server burst",
    "server_runq_cores": "CPU stage: mean run-queue wait of the server's process, in cores",
    "host_runq_cores_mean": "CPU stage: mean run-queue wait of the host processes, in cores",
    "host_cpu_util_max": "CPU stage: busiest host process's busy fraction",
    "machine_cpu_util_max": "CPU stage: busiest machine's utilisation",
    "buffer_bytes_peak": "peak bytes held by the alignment server's buffers",
    "rollbacks": "BiDES time-warp rollbacks",
    "resim_steps": "physics steps re-simulated after rollbacks",
    "evicted": "nodes Lock-Step evicted (missing longer than `eviction_timeout`)",
    "rejoined": "evicted nodes that rejoined Lock-Step (by delivering the newest frame)",
    "rerequests": "states Lock-Step re-requested after `retry_timeout` (0 for the others)",
    "history_misses": "rollbacks whose checkpoint had left a node's history",
    "formation_err_mean": "distance of a node's offset from the swarm centroid to its "
                          "offset in the ideal run, mean over nodes and time",
    "formation_err_max": "the same, maximum over time",
    "dtw_r": "per-node DTW distance to the ideal trajectory, normalised (mean deviation per "
             "sample), averaged over `fidelity.dtw_nodes` nodes",
    "rejected": "live: messages dropped as malformed",
    "unknown_topic": "live: messages on an unknown topic",
    "reconnects": "live: client reconnects",
    "missed_frac": "live: share of node × frame states of the window that never arrived",
    "late": "live: states that arrived after the run",
    "wall_s": "wall-clock time of the run",
    "events": "events the engine processed",
    "events_per_s": "events per wall-clock second",
    "peak_rss_mb": "peak resident memory of the process",
    "speed_x_realtime": "simulated seconds per wall-clock second",
}

_COLUMNS = {
    "seed": "the scenario's root seed",
    "config_hash": "12-hex-digit hash of the scenario (seed, methods, engine and `record` "
                   "excluded): rows of one scenario share it",
    "version": "sigma_des version that wrote the row",
    "method": "alignment method (`none`, `lockstep`, `hlc`, `bides`, `rpc`)",
    "metric": "metric name (tables below; `link_mbps.<link>.<dir>` per link direction)",
    "value": "the metric's value (NaN where undefined)",
    "unit": "the metric's unit",
}

_SUMMARY = {
    "mode": '`"des"` (simulated) or `"live"`',
    "version": "sigma_des version",
    "seed": "the scenario's root seed",
    "config_hash": "the scenario's hash (as in results.csv)",
    "scenario": "the resolved scenario, every key (as `sigma-des config` prints it)",
    "methods": "per method, its metrics (`{method: {metric: value}}`)",
    "links_mbps": "per method, the wire rate of every link direction",
    "wall": "per method, the run's cost (the wall.csv metrics)",
    "engines": "per method, the engine `requested` and `used`, and why it fell back",
    "live": "live runs only: per method, the live counters",
    "interrupted": "present and true when the run was stopped early (Ctrl-C)",
}


def _metrics_table(units: dict[str, str]) -> list[str]:
    missing = sorted(set(units) - set(METRIC_DOCS))
    if missing:
        raise RuntimeError(f"metrics without a description in {__file__}: {missing}")
    rows = ["| Metric | Unit | What it measures |", "| --- | --- | --- |"]
    rows += [f"| `{m}` | {u} | {METRIC_DOCS[m]} |" for m, u in units.items()]
    return rows


def _schema_rows(props: dict[str, Any], prefix: str = "") -> list[str]:
    rows = []
    for name, p in props.items():
        kind = p.get("type", "object")
        if kind == "array":
            kind = f"array of {p['items'].get('type', 'object')}"
        desc = myst_inline(p.get("description", p.get("title", "")))
        rows.append(f"| `{prefix}{name}` | {kind} | {desc} |")
        if p.get("type") == "object" and "properties" in p and not p.get("title"):
            rows += _schema_rows(p["properties"], f"{prefix}{name}.")
        items = p.get("items", {})
        if isinstance(items, dict) and "properties" in items and not items.get("title"):
            rows += _schema_rows(items["properties"], f"{prefix}{name}[].")
    return rows


def _mcap() -> list[str]:
    out = ["## MCAP recording (`--record FILE.mcap`)", "",
           "One channel per method and message kind, topic `/<method>/<kind>`, JSON "
           "messages with a JSON schema (Foxglove and Lichtblick read them). The schema "
           "depends on `record.mode`:", "",
           "| Kind | Topic | Schema (`full`) | Schema (`incremental`) |",
           "| --- | --- | --- | --- |"]
    out += [f"| {k} | `/<method>/{k}` | `{SCHEMAS[(k, 'full')][0]}` | "
            f"`{SCHEMAS[(k, 'incremental')][0]}` |" for k in KINDS]
    seen: set[str] = set()
    for (_kind, _mode), (name, schema) in SCHEMAS.items():
        if name in seen:
            continue
        seen.add(name)
        out += ["", f"### `{name}`", "", myst_inline(schema.get("description", "")), "",
                "| Field | Type | Meaning |", "| --- | --- | --- |",
                *_schema_rows(schema["properties"])]
    return out


def outputs_page() -> str:
    """The page as MyST Markdown."""
    summary = Results(Scenario()).summary()
    unknown = sorted(set(summary) - set(_SUMMARY))
    if unknown:
        raise RuntimeError(f"summary.json keys without a description in {__file__}: {unknown}")
    out = ["# Output files", "",
           "`sigma-des compare --out DIR` (and `live --out`) writes `results.csv`, "
           "`wall.csv`, `summary.json` and PNG plots into `DIR`, all or none. "
           "`results.csv` is deterministic: the same scenario and seed give the same "
           "bytes; `wall.csv` holds what varies from run to run (the simulator's cost).",
           "", "## `results.csv` and `wall.csv`", "",
           "Tidy tables: one row per method × metric.", "",
           "| Column | Meaning |", "| --- | --- |",
           *[f"| `{c}` | {_COLUMNS[c]} |" for c in TIDY_COLUMNS], "",
           "### Metrics (`results.csv`)", "",
           "Metrics of the CPU stage appear only with `deployment.preset` other than "
           "`none`; live metrics only in live runs.", "",
           *_metrics_table(METRIC_UNITS), "",
           "### Run cost (`wall.csv`)", "", *_metrics_table(WALL_METRICS), "",
           "## `summary.json`", "", "| Key | Meaning |", "| --- | --- |",
           *[f"| `{k}` | {v} |" for k, v in _SUMMARY.items()], "", *_mcap(), ""]
    return "\n".join(out)
