"""Accumulates one run's measurements and turns them into metrics (docs/concepts/metrics.md).

The engine reports deliveries, triggers, snapshot changes and render ticks; the
collector keeps only what the metrics need (samples after the warm-up) and, at
the end, returns a flat ``{metric: value}`` dict plus per-render-tick time
series. Times are reported in milliseconds, rates in Hz, throughput in Mbps of
wire bits (every packet on every link, headers and framing included). It knows
neither the scenario nor the engines: it is built from a :class:`CollectorSpec` and
finishes from the components' typed reports (:mod:`sigma_des.metrics.reports`).
"""

from __future__ import annotations

import math
import resource
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.flags import EXTRAPOLATED, FILLED
from sigma_des.core.validate import require, require_positive
from sigma_des.metrics.aoi import AoITracker
from sigma_des.metrics.reports import AlignerReport, NetReport, RunReport
from sigma_des.metrics.samples import Samples
from sigma_des.metrics.throughput import link_mbps, throughput
from sigma_des.net.cpu import CpuReport
from sigma_des.net.kinds import KIND_NAMES, REPUBLISH, STATE

__all__ = ["Collector", "CollectorSpec", "METRIC_UNITS", "WALL_METRICS",
           "cpu_metrics"]

#: the truth of a render tick that has none (no rows)
_NO_TRUTH = np.empty((0, 3))
#: latency series of each message kind (a republished state is a state)
_KINDS = {**KIND_NAMES, REPUBLISH: KIND_NAMES[STATE]}

#: Unit of every metric the collector reports.
METRIC_UNITS: dict[str, str] = {
    **{f"aoi_{s}": "ms" for s in ("mean", "std", "p50", "p95", "p99", "max")},
    "aoi_time_avg": "ms",
    "aoi_peak_mean": "ms",
    **{f"latency_{k}_{s}": "ms" for k in ("state", "trigger", "command") for s in ("mean", "p99")},
    "throughput_mbps": "Mbps",
    "throughput_max_link_mbps": "Mbps",
    "packets_per_s": "1/s",
    "deliveries_per_s": "1/s",
    "trigger_rate_hz": "Hz",
    "f_trig_final_hz": "Hz",
    "f_trig_min_hz": "Hz",
    "snapshot_rate_hz": "Hz",
    "snapshot_interval_std_ms": "ms",
    "stalls": "count",
    "stall_time_s": "s",
    "spread_mean": "frames",
    "spread_max": "frames",
    "pos_err_mean": "m",
    "pos_err_max": "m",
    "filled_frac": "1",
    "extrapolated_frac": "1",
    "off_frame_frac": "1",
    "duplicates": "count",
    "retransmissions": "count",
    "gave_up": "count",
    "broker_util": "1",
    "broker_max_wait_ms": "ms",
    # only with a CPU stage (deployment.preset colocated or dedicated; absent otherwise)
    "server_cpu_util": "1",
    "server_cpu_max_wait_ms": "ms",
    "server_runq_cores": "cores",
    "host_runq_cores_mean": "cores",
    "host_cpu_util_max": "1",
    "machine_cpu_util_max": "1",
    "buffer_bytes_peak": "B",
    "rollbacks": "count",
    "resim_steps": "count",
    "evicted": "count",
    "rejoined": "count",
    "rerequests": "count",
    "history_misses": "count",
    "formation_err_mean": "m",
    "formation_err_max": "m",
    "dtw_r": "m",
    # live mode only (sigma_des.live): messages dropped as malformed / on unknown topics,
    # client reconnects, node x frame states of the window that never arrived, states
    # that arrived after the run
    "rejected": "count",
    "unknown_topic": "count",
    "reconnects": "count",
    "missed_frac": "1",
    "late": "count",
}
#: Metrics that measure the simulator itself (vary run to run; kept apart).
WALL_METRICS: dict[str, str] = {
    "wall_s": "s",
    "events": "count",
    "events_per_s": "1/s",
    "peak_rss_mb": "MB",
    "speed_x_realtime": "x",
}


@dataclass(frozen=True)
class CollectorSpec:
    """What the collector needs to know of the run (the scenario builds it).

    Attributes:
        nodes: number of nodes.
        warmup: samples before this time (s) are left out.
        duration: end of the run (s).
        f_trig: nominal trigger rate (Hz; the start of ``f_trig_min_hz``).
        history_frames: indices remembered per subject to spot duplicate deliveries.
        stall_threshold: a gap between new snapshots longer than this is a stall (s).
    """

    nodes: int
    warmup: float
    duration: float
    f_trig: float
    history_frames: int
    stall_threshold: float

    def __post_init__(self) -> None:
        require(self.nodes >= 1, "nodes", f"must be >= 1, got {self.nodes}")
        require(
            0 <= self.warmup < self.duration,
            "warmup",
            f"must be in [0, duration = {self.duration}), got {self.warmup}",
        )
        require_positive(self, "f_trig", "stall_threshold")
        require(
            self.history_frames >= 1,
            "history_frames",
            f"must be >= 1, got {self.history_frames}",
        )


class Collector:
    """Measurement sink of one run (an engine's or the live server's).

    Args:
        spec: what it needs to know of the run.
        method: the alignment method's name (for the results).
    """

    def __init__(self, spec: CollectorSpec, method: str) -> None:
        self.spec = spec
        self.method = method
        self.w0 = spec.warmup
        n = spec.nodes
        self.aoi = AoITracker(n, spec.warmup)
        self._shown_gen = np.full(n, np.nan)  # generation times shown after the last tick
        # scratch of one tick: changed nodes and their states, ages and position errors
        self._nodes = np.empty(n, dtype=np.int64)
        self._gens = np.empty(n)
        self._ages = np.empty(n)
        self._errs = np.empty(n)
        H = spec.history_frames
        # per kind, the newest index seen per (subject, index % H): made on first use, so
        # a run that never calls delivered() (the cohort engine) never holds them
        self._seen: dict[int, NDArray[np.int64]] = {}
        self._seen_shape = (n + 1, H)
        # samples needed whole at the end (exact percentiles and whole-sample means),
        # 8 bytes each (sigma_des.metrics.samples)
        self._lat = {k: Samples() for k in ("trigger", "state", "command")}
        self.duplicates = 0
        self.messages = 0
        self.triggers = 0
        self.f_trig_min = spec.f_trig
        self._snap_times: list[float] = []
        self._aoi_samples = Samples()
        self._spread: list[int] = []
        self._pos_err = Samples()
        self._flag_counts = [0, 0, 0, 0]  # shown, filled, extrapolated, off the ref frame
        self.ts: dict[str, list[float]] = {
            k: []
            for k in (
                "t",
                "aoi_mean",
                "aoi_max",
                "spread",
                "f_trig",
                "latest_trigger",
                "aligned_frame",
            )
        }

    # ------------------------------------------------------------ events

    def trigger(self, t: float, k: int, dt: float) -> None:
        """Trigger ``k`` was issued at ``t``."""
        if t >= self.w0:
            self.triggers += 1
            # the rate in force for this trigger (a rate set before the window counts too)
            self.f_trig_min = min(self.f_trig_min, 1.0 / dt)

    def rate_change(self, t: float, f: float) -> None:
        """The trigger rate changed to ``f``."""
        if t >= self.w0:
            self.f_trig_min = min(self.f_trig_min, f)

    def delivered(self, kind: int, subject: int, index: int, t_pub: float, t: float) -> None:
        """A PUBLISH reached its receiver (first delivery counts; later ones are duplicates)."""
        seen = self._seen.get(kind)
        if seen is None:
            seen = self._seen[kind] = np.full(self._seen_shape, -1, dtype=np.int64)
        slot = index % seen.shape[1]
        if seen[subject, slot] == index:
            self.duplicates += 1
            return
        seen[subject, slot] = index
        if t_pub >= self.w0:
            self.messages += 1
            name = _KINDS[kind]
            if name in self._lat:
                self._lat[name].append(t - t_pub)

    def delivered_batch(
        self, kind: int, latencies: NDArray[np.float64], messages: int, duplicates: int = 0
    ) -> None:
        """Many deliveries of ``kind`` (the cohort engine's path, which tells duplicates).

        Args:
            kind: message kind (its latency series gets ``latencies``, in order).
            latencies: delivery latencies (s) of the counted messages.
            messages: number of counted first deliveries (published after the warm-up).
            duplicates: number of duplicate deliveries (not in ``messages``).
        """
        self.messages += messages
        self.duplicates += duplicates
        name = _KINDS[kind]
        if name in self._lat and latencies.size:
            self._lat[name].extend(latencies)

    def aoi_update(self, t: float, nodes: NDArray[np.int64], gens: NDArray[np.float64]) -> None:
        """The consumer starts showing new states of ``nodes``."""
        self.aoi.update(t, nodes, gens)

    def shown(self, t: float, gen: NDArray[np.float64]) -> None:
        """The consumer shows states generated at ``gen`` (NaN: none yet) from tick ``t`` on.

        Only the nodes whose shown state changed since the previous tick start a new AoI
        sawtooth (:meth:`aoi_update`); every engine and the live server call this.
        """
        # numba: imported on first use (the scenario's modules import no numba)
        from sigma_des.metrics.tick_kernels import changed_states

        gen = np.ascontiguousarray(gen, dtype=np.float64)
        if gen.shape != self._shown_gen.shape:
            raise ValueError(f"shown: {self.spec.nodes} generation times expected, "
                             f"got shape {gen.shape}")
        k = changed_states(gen, self._shown_gen, self._nodes, self._gens)
        if k:
            self.aoi_update(t, self._nodes[:k], self._gens[:k])
            self._shown_gen = gen.copy()

    def snapshot(self, t: float) -> None:
        """A new aligned snapshot appeared at ``t``."""
        if t >= self.w0:
            self._snap_times.append(t)

    def render(
        self,
        t: float,
        gen: NDArray[np.float64],
        frame: NDArray[np.int64],
        obs: NDArray[np.float64],
        flag: NDArray[np.uint8],
        truth: NDArray[np.float64] | None,
        f_trig: float,
        latest: int,
        ref: int,
    ) -> None:
        """A render tick: sample AoI and consistency of the shown snapshot."""
        if t < self.w0:
            return
        # the nodes with a state: their ages, frame spread, position errors (NaN ones left
        # out), the flag counts, the ages' mean (numpy's) and maximum: one compiled pass
        # (metrics/tick_kernels.py)
        from sigma_des.metrics.tick_kernels import render_sample  # numba: on first use

        n = self.spec.nodes
        pos = _NO_TRUTH if truth is None else np.ascontiguousarray(truth, dtype=np.float64)
        if gen.shape != (n,) or frame.shape != (n,) or obs.shape[:1] != (n,) or \
                obs.shape[1:] < (12,) or pos.shape not in ((n, 3), (0, 3)):
            raise ValueError(f"render: rows of {n} nodes expected, got gen {gen.shape}, "
                             f"frame {frame.shape}, obs {obs.shape}, truth {pos.shape}")
        k, m, spread, filled, extrapolated, off, mean, hi = render_sample(
            float(t), np.ascontiguousarray(gen, dtype=np.float64),
            np.ascontiguousarray(frame, dtype=np.int64),
            np.ascontiguousarray(obs, dtype=np.float64), np.ascontiguousarray(flag), pos,
            int(ref), FILLED, EXTRAPOLATED, self._ages, self._errs)
        self._aoi_samples.extend(self._ages[:k])
        self._spread.append(spread)
        if m:
            self._pos_err.extend(self._errs[:m])
        self._flag_counts[0] += k
        self._flag_counts[1] += filled
        self._flag_counts[2] += extrapolated
        if ref >= 0:
            self._flag_counts[3] += off
        ts = self.ts
        ts["t"].append(t)
        ts["aoi_mean"].append(mean)
        ts["aoi_max"].append(hi)
        ts["spread"].append(spread)
        ts["f_trig"].append(f_trig)
        ts["latest_trigger"].append(latest)
        ts["aligned_frame"].append(ref)

    def latencies(self, kind: str) -> NDArray[np.float64]:
        """The delivery latencies (s) counted so far of ``kind`` (``trigger``, ``state``,
        ``command``), in delivery order (a copy)."""
        return self._lat[kind].values().copy()

    def aoi_samples(self) -> NDArray[np.float64]:
        """The AoI samples (s) taken so far at the render ticks, in order (a copy)."""
        return self._aoi_samples.values().copy()

    def sample_bytes(self) -> int:
        """Bytes held by the samples kept whole for the end (latencies, AoI, errors)."""
        held = [*self._lat.values(), self._aoi_samples, self._pos_err]
        return sum(s.nbytes for s in held)

    # ------------------------------------------------------------ results

    def finish(self, run: RunReport, aligner: AlignerReport, net: NetReport,
               cpu: CpuReport | None = None) -> dict[str, Any]:
        """Metrics of the finished run (see :data:`METRIC_UNITS`, :data:`WALL_METRICS`).

        Args:
            run: the engine's (or live server's) report on the run itself.
            aligner: the alignment method's report.
            net: the network's counters.
            cpu: the CPU stage's counters (None: no CPU stage; its metrics are then
                absent, not NaN, so a run without one has exactly the rows it had).

        Returns:
            ``{"metrics", "wall", "links_mbps", "timeseries"}``.
        """
        # numba's kernels, loaded when a run ends: the scenario's modules import no numba
        from sigma_des.metrics.streamed import store_mean_max, summarize_store

        sc = self.spec
        window = sc.duration - self.w0
        m: dict[str, float] = {}
        ms = 1000.0
        a = summarize_store(self._aoi_samples)  # bounded memory, same bits (streamed)
        for s in ("mean", "std", "p50", "p95", "p99", "max"):
            m[f"aoi_{s}"] = a[s] * ms
        fin = self.aoi.finish(sc.duration)
        m["aoi_time_avg"] = fin["time_average"] * ms
        m["aoi_peak_mean"] = fin["peak_mean"] * ms
        for kind, xs in self._lat.items():
            lat = summarize_store(xs)
            m[f"latency_{kind}_mean"] = lat["mean"] * ms
            m[f"latency_{kind}_p99"] = lat["p99"] * ms
        m.update(throughput(net.links, window))
        m["deliveries_per_s"] = self.messages / window
        m["trigger_rate_hz"] = self.triggers / window
        m["f_trig_final_hz"] = run.f_trig
        m["f_trig_min_hz"] = self.f_trig_min
        snaps = np.asarray(self._snap_times)
        m["snapshot_rate_hz"] = snaps.size / window
        gaps = np.diff(np.concatenate([[self.w0], snaps, [sc.duration]]))
        m["snapshot_interval_std_ms"] = (
            float(np.std(np.diff(snaps))) * ms if snaps.size > 2 else math.nan
        )
        stall = gaps > sc.stall_threshold
        m["stalls"] = int(stall.sum())
        m["stall_time_s"] = float(gaps[stall].sum())
        sp = np.asarray(self._spread, dtype=np.float64)
        m["spread_mean"] = float(sp.mean()) if sp.size else math.nan
        m["spread_max"] = float(sp.max()) if sp.size else math.nan
        m["pos_err_mean"], m["pos_err_max"] = store_mean_max(self._pos_err)
        shown = max(1, self._flag_counts[0])
        m["filled_frac"] = self._flag_counts[1] / shown
        m["extrapolated_frac"] = self._flag_counts[2] / shown
        m["off_frame_frac"] = self._flag_counts[3] / shown
        m["duplicates"] = self.duplicates
        m["retransmissions"] = net.retransmissions
        m["gave_up"] = net.gave_up
        m["broker_util"] = net.broker_work / window
        m["broker_max_wait_ms"] = net.broker_max_wait * ms
        m["buffer_bytes_peak"] = aligner.peak_bytes
        m["rollbacks"] = run.rollbacks
        m["resim_steps"] = run.resim_steps
        m["evicted"] = aligner.evicted
        m["rejoined"] = aligner.rejoined
        m["rerequests"] = aligner.rerequests
        m["history_misses"] = run.history_misses
        if cpu is not None:
            m.update(cpu_metrics(cpu, window))
        wall = {
            "wall_s": run.wall_seconds,
            "events": run.events,
            "events_per_s": run.events / max(run.wall_seconds, 1e-9),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "speed_x_realtime": sc.duration / max(run.wall_seconds, 1e-9),
        }
        return {
            "metrics": m,
            "wall": wall,
            "links_mbps": link_mbps(net.links, window),
            "timeseries": whole_ticks(self.ts),
        }


def cpu_metrics(cpu: CpuReport, window: float) -> dict[str, float]:
    """The CPU stage's metrics: the server's utilisation (CPU seconds held per second of
    the window) and longest wait, the busiest host process's utilisation, and the
    busiest machine's (its processes' CPU seconds over cores x window, background
    excluded)."""
    procs = {p.name: p for p in cpu.processes}
    server = procs["server"]
    hosts = [p.busy for p in cpu.processes if p.name.startswith("host")]
    per_machine: dict[str, float] = {}
    for p in cpu.processes:
        per_machine[p.machine] = per_machine.get(p.machine, 0.0) + p.busy
    out = {
        "server_cpu_util": server.busy / window,
        "server_cpu_max_wait_ms": server.max_wait * 1000.0,
        "host_cpu_util_max": max(hosts, default=0.0) / window,
        "machine_cpu_util_max": max(per_machine.values()) / (cpu.cores * window),
    }
    if any(p.queued > 0.0 for p in cpu.processes):  # run-queue waits modelled
        waits = [p.queued for p in cpu.processes if p.name.startswith("host")]
        out["server_runq_cores"] = server.queued / window
        out["host_runq_cores_mean"] = sum(waits) / max(len(waits), 1) / window
    return out


def whole_ticks(ts: dict[str, list[Any]]) -> dict[str, NDArray[Any]]:
    """The per-render-tick series as arrays, cut to the ticks every series has.

    A run stopped in the middle of a render tick (Ctrl-C in live mode raises
    ``KeyboardInterrupt`` between two appends) leaves some series one sample
    longer than others; plots and tables need whole ticks. A complete run's
    series all have the same length, so nothing is cut.
    """
    n = min((len(v) for v in ts.values()), default=0)
    return {k: np.asarray(v[:n]) for k, v in ts.items()}

