"""The alignment-cost study's timings: one alignment step per method, as implemented.

``experiments/alignment_cost.py`` (the script: command line, plot, outputs) times,
for every n and seed, with :func:`timed` (``time.perf_counter`` over repeats):

* ``bides`` — Algorithm 1 (:func:`sigma_des.events.align.ring.align`) over
  :class:`~sigma_des.events.align.ring.RingBuffers` with k = 30, filled the way a
  running swarm leaves them: each node's newest frame a few frames behind the
  swarm's newest (most 0–2 behind, some 3–5, ~2 % beyond Θ_lag = 3 and so
  excluded), ~5 % of the buffered frames lost (holes), hole filling and lag
  exclusion on — the configuration the engine runs;
* ``hlc`` — one alignment tick of the HLC consumer
  (:class:`~sigma_des.events.align.hlc.HLCAligner`): liveness check, stability
  bound, release of the causally stable states in HLC order, with the states of
  100/60 frames per node arriving between ticks (100 Hz physics, 60 Hz alignment);
* ``lockstep`` — the Lock-Step barrier
  (:class:`~sigma_des.events.align.lockstep.LockstepAligner`): its alignment tick, and
  the per-frame cost of receiving all n states (the barrier's completeness check
  runs on every arrival).

:func:`record` reduces one case's timings to median, p95 and repeats (tidy rows).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

import sigma_des
from sigma_des import Scenario
from sigma_des.events.align.base import OBS_WIDTH, one_state
from sigma_des.events.align.hlc import HLCAligner
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.align.lockstep import LockstepAligner
from sigma_des.events.align.ring import RingBuffers, align

NAME = "alignment_cost"
K = 30
THETA_LAG = 3
HOLE_P = 0.05
F_TRIG = 100.0
F_ALIGN = 60.0

class StubContext:
    """A minimal :class:`~sigma_des.events.align.base.ServerContext` (timers are dropped)."""

    def __init__(self) -> None:
        self.latest_trigger = 0
        self.f_trig = F_TRIG
        self.t = 0.0
        self.barriers = 0

    def now(self) -> float:
        """Current time."""
        return self.t

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        """Drop timers: retries and evictions never fire in this benchmark."""

    def set_rate(self, f_trig: float) -> None:
        """Record a rate change."""
        self.f_trig = f_trig

    def barrier_done(self, frame: int) -> None:
        """Count completed barriers."""
        self.barriers += 1

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        """Never called (timers are dropped)."""


def filled_rings(n: int, seed: int, top: int = 1000) -> tuple[RingBuffers, int]:
    """Ring buffers of ``n`` nodes as a running swarm leaves them.

    Returns:
        The buffers and the previous aligned frame to pass to ``align``.
    """
    rng = np.random.default_rng(seed)
    u = rng.random(n)
    lag = np.where(u < 0.90, rng.integers(0, 3, n), rng.integers(3, 6, n))
    lag = np.where(u > 0.98, rng.integers(6, 16, n), lag)
    latest = top - lag
    frames = latest[:, None] - np.arange(K)[None, :]
    keep = rng.random(frames.shape) >= HOLE_P
    keep[:, 0] = True  # the newest frame arrived (it defines `latest`)
    nodes = np.broadcast_to(np.arange(n)[:, None], frames.shape)[keep]
    fr = frames[keep]
    gen = fr / F_TRIG + 0.002
    obs = rng.standard_normal((fr.size, OBS_WIDTH))
    buf = RingBuffers(n, K, OBS_WIDTH)
    buf.insert(nodes, fr, gen, obs)
    return buf, top - 8


def timed(fn: Callable[[], Any], budget: float, min_reps: int, max_reps: int) -> np.ndarray:
    """Call ``fn`` repeatedly (at least ``min_reps``, until ``budget`` s or ``max_reps``).

    Returns:
        Wall time of every call (s).
    """
    fn()  # warm caches
    out: list[float] = []
    start = time.perf_counter()
    while len(out) < max_reps and (len(out) < min_reps or time.perf_counter() - start < budget):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return np.asarray(out)


def bench_bides(n: int, seed: int, budget: float) -> dict[str, np.ndarray]:
    """Algorithm 1 on filled rings, and inserting one frame of n states."""
    buf, prev = filled_rings(n, seed)
    res = align(buf, theta_lag=THETA_LAG, hole_fill=True, prev_frame=prev)
    assert res.aligned_frame >= prev
    t_align = timed(
        lambda: align(buf, theta_lag=THETA_LAG, hole_fill=True, prev_frame=prev),
        budget,
        5,
        500,
    )
    obs = np.zeros(OBS_WIDTH)
    state = {"frame": 2000}

    def ingest() -> None:
        f = state["frame"]
        state["frame"] += 1
        for i in range(n):
            buf.insert(i, f, f / F_TRIG, obs)

    t_ingest = timed(ingest, budget, 3, 200)
    return {"align": t_align, "ingest": t_ingest}


def scenario(n: int) -> Scenario:
    """A one-host scenario of ``n`` nodes at the study's rates (the aligners' settings)."""
    return Scenario(nodes=n, hosts=1, f_trig=F_TRIG, f_align=F_ALIGN)


def bench_hlc(n: int, seed: int, budget: float) -> dict[str, np.ndarray]:
    """HLC: per tick, the arrivals of 100/60 frames per node, then one alignment tick."""
    ctx = StubContext()
    al = HLCAligner(n, scenario(n).hlc, ctx)
    rng = np.random.default_rng(seed)
    jitter = rng.uniform(0, 0.004, size=n).tolist()
    obs = np.zeros(OBS_WIDTH)
    state: dict[str, Any] = {"frame": 0, "acc": 0.0, "tick": 0}

    def arrivals() -> None:
        state["acc"] += F_TRIG / F_ALIGN
        while state["acc"] >= 1.0:
            state["acc"] -= 1.0
            f = state["frame"]
            state["frame"] += 1
            base = f / F_TRIG
            for i in range(n):
                g = base + jitter[i]
                al.on_states(one_state(g, i, f, g, obs, Stamp(g, 0)))

    def tick() -> None:
        state["tick"] += 1
        al.align(state["frame"] / F_TRIG)

    for _ in range(3):  # reach a steady buffer
        arrivals()
        tick()
    t_ing: list[float] = []
    t_al: list[float] = []
    start = time.perf_counter()
    while len(t_al) < 200 and (len(t_al) < 5 or time.perf_counter() - start < budget):
        t0 = time.perf_counter()
        arrivals()
        t1 = time.perf_counter()
        tick()
        t2 = time.perf_counter()
        t_ing.append(t1 - t0)
        t_al.append(t2 - t1)
    return {"align": np.asarray(t_al), "ingest": np.asarray(t_ing)}


def bench_lockstep(n: int, seed: int, budget: float) -> dict[str, np.ndarray]:
    """Lock-Step: one frame's n arrivals (barrier bookkeeping), then one alignment tick."""
    ctx = StubContext()
    al = LockstepAligner(n, scenario(n).lockstep, ctx)
    rng = np.random.default_rng(seed)
    order = rng.permutation(n).tolist()
    obs = np.zeros(OBS_WIDTH)
    state = {"frame": 0}
    t_ing: list[float] = []
    t_al: list[float] = []
    start = time.perf_counter()
    while len(t_al) < 200 and (len(t_al) < 3 or time.perf_counter() - start < budget):
        f = state["frame"]
        state["frame"] += 1
        t = f / F_TRIG
        t0 = time.perf_counter()
        al.on_trigger(f, t)
        for i in order:
            al.on_states(one_state(t, i, f, t, obs))
        t1 = time.perf_counter()
        al.align(t)
        t2 = time.perf_counter()
        t_ing.append(t1 - t0)
        t_al.append(t2 - t1)
    assert ctx.barriers == len(t_al)
    return {"align": np.asarray(t_al), "ingest": np.asarray(t_ing)}


BENCHES = {"bides": bench_bides, "hlc": bench_hlc, "lockstep": bench_lockstep}
WHAT = {
    ("bides", "align"): "Algorithm 1 (align over ring buffers, k = 30)",
    ("bides", "ingest"): "ring-buffer insert of one frame's n states",
    ("hlc", "align"): "HLC alignment tick (stability bound + release)",
    ("hlc", "ingest"): "HLC buffer pushes of one tick's arrivals (100/60 frames × n)",
    ("lockstep", "align"): "Lock-Step alignment tick (copy completed frame)",
    ("lockstep", "ingest"): "Lock-Step barrier: one frame's n arrivals",
}


def record(
    times: dict[str, np.ndarray], cell: dict[str, list[float]], n: int, seed: int,
    method: str, chash: str,
) -> list[dict[str, Any]]:
    """Median, p95 and repeats of each timed part into ``cell``; their tidy rows; a line."""
    rows: list[dict[str, Any]] = []
    for part, xs in times.items():
        ms = xs * 1000.0
        vals = {
            f"{part}_median_ms": float(np.median(ms)),
            f"{part}_p95_ms": float(np.percentile(ms, 95)),
            f"{part}_reps": float(ms.size),
        }
        for k, v in vals.items():
            cell.setdefault(k, []).append(v)
            rows.append(
                {
                    "study": NAME,
                    "variant": f"n={n}",
                    "seed": seed,
                    "config_hash": chash,
                    "version": sigma_des.__version__,
                    "method": method,
                    "metric": k,
                    "value": v,
                    "unit": "count" if k.endswith("reps") else "ms",
                }
            )
    print(
        f"n={n:6d} {method:9s} "
        + "  ".join(
            f"{p}: median {np.median(x) * 1e3:8.3f} ms p95 "
            f"{np.percentile(x, 95) * 1e3:8.3f} ms"
            for p, x in times.items()
        ),
        flush=True,
    )
    return rows
