#!/usr/bin/env python
"""Benchmark the MCAP recorder and the replay (issue 12's size, overhead and speed goals).

Runs one method of the default scenario (6-DoF quadrotors, formation, 100 Hz) at
``--nodes`` for ``--duration`` simulated seconds three times in this process — not
recorded, recorded ``full``, recorded ``incremental`` (dead-bands ``--deadband-pos``,
``--deadband-vel``, ``--deadband-att``, keyframes every ``--keyframe-every`` frames)
— after a short warm-up run (numba caches). It prints and writes (``--out``, JSON):

* wall and CPU time of each run, the recording overhead (recorded / not recorded − 1)
  and the recorder's CPU cost: the CPU time spent inside the recording tap's calls
  (``tap_cpu_s``: encoding, JSON, compression, writing), and recorded CPU − not
  recorded CPU (``recorder_cpu_s``, noisier);
* file size of both recordings and the ratio full / incremental; states stored;
* reconstruction error of the incremental file: every state of the full recording is
  rebuilt from the incremental one (``hermite-dw``, window ``none`` as in the replay, on
  the stored states, at the full recording's instants): mean, p99 and max 3-D error (m);
* replay of the incremental file to ``--rate`` Hz for all nodes (``hermite-dw``):
  the read + rebuild time and, apart, the CSV write time.

The issue's goals: ≥ 5× smaller at a dead-band that keeps the error < 0.1 m, overhead
< 10 %, replay of a 1000-node 60 s file to 60 Hz in < 5 s.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des import compare, load
from sigma_des.record import open_recording, read_states
from sigma_des.replay import WindowRule, interpolate
from sigma_des.replay.replay import node_samples, replay


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--hosts", type=int, default=10)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--method", default="none")
    p.add_argument("--deadband-pos", type=float, default=0.05)
    p.add_argument("--deadband-vel", type=float, default=0.1)
    p.add_argument("--deadband-att", type=float, default=0.02)
    p.add_argument("--keyframe-every", type=int, default=100)
    p.add_argument("--rate", type=float, default=60.0)
    p.add_argument("--no-replay", action="store_true",
                   help="skip the reconstruction error and the replay (only runs and sizes)")
    p.add_argument("--dir", default=None, help="keep the recordings here (default: temp)")
    p.add_argument("--out", default=None, help="write the figures as JSON here")
    p.add_argument("--reuse", action="store_true",
                   help="keep the run figures of --out and the recordings in --dir; redo only "
                   "the reconstruction and replay measurements")
    p.add_argument("--reuse-from", default=None, metavar="JSON",
                   help="with --reuse: take the plain and full run figures from this JSON and "
                   "record the incremental run again (new dead-bands; same scenario and seed, "
                   "so the kept full.mcap is its reference)")
    return p


TAP_CPU = {"s": 0.0}  # CPU time inside the recording tap's calls (see _time_the_tap)


def _time_the_tap() -> None:
    """Wrap every hook of the recording tap with a CPU timer (runs are in-process)."""
    from sigma_des.record.tap import RecordTap

    def timer(f: Any) -> Any:
        def timed(*args: object, **kw: object) -> object:
            c0 = time.process_time()
            try:
                return f(*args, **kw)
            finally:
                TAP_CPU["s"] += time.process_time() - c0
        return timed

    for name in ("trigger", "states", "commands", "snapshot", "render", "close"):
        setattr(RecordTap, name, timer(getattr(RecordTap, name)))


def _run(sets: list[str], method: str, record: Path | None) -> tuple[float, float, float]:
    """Wall time, CPU time and CPU time inside the recording tap (s) of one run."""
    sc = load(None, sets)
    TAP_CPU["s"] = 0.0
    t0, c0 = time.perf_counter(), time.process_time()
    compare(sc, methods=[method], progress=False, record=record)
    return time.perf_counter() - t0, time.process_time() - c0, TAP_CPU["s"]


def reconstruction_error(full: Path, inc: Path, method: str) -> dict[str, float]:
    """3-D error of the incremental file, rebuilt at every state of the full one."""
    a = read_states(full, method)[method]
    b = read_states(inc, method)[method]
    errs = []
    for node in np.unique(a.node).tolist():
        _f, t, pos, _v, _att = node_samples(a, node)
        _g, tb, pb, vb, ab = node_samples(b, node)
        got = interpolate(tb, pb, "hermite-dw", at=t, velocities=vb, attitudes=ab,
                          window=WindowRule(rule="none"))  # the replay's default
        ok = ~np.isnan(got).any(axis=1)  # after the last stored state: not rebuilt
        errs.append(np.linalg.norm(got[ok] - pos[ok], axis=1))
    e = np.concatenate(errs)
    return {"mean_m": float(e.mean()), "p99_m": float(np.quantile(e, 0.99)),
            "max_m": float(e.max()), "states_compared": int(e.size)}


def main(argv: list[str] | None = None) -> int:
    a = parser().parse_args(argv)
    _time_the_tap()
    d = Path(a.dir) if a.dir else Path(tempfile.mkdtemp(prefix="bench_record_"))
    d.mkdir(parents=True, exist_ok=True)
    base = [f"nodes={a.nodes}", f"hosts={a.hosts}", f"duration={a.duration}",
            f"warmup={min(1.0, a.duration / 5)}",
            "fidelity.enabled=false"]
    inc_sets = [*base, "record.mode=incremental", f"record.deadband_pos={a.deadband_pos}",
                f"record.deadband_vel={a.deadband_vel}",
                f"record.deadband_att={a.deadband_att}",
                f"record.keyframe_every={a.keyframe_every}"]
    full, inc = d / "full.mcap", d / "incremental.mcap"
    if a.reuse:
        prev = Path(a.reuse_from or a.out or "")
        if not (prev.is_file() and full.is_file() and (inc.is_file() or a.reuse_from)):
            print("--reuse needs a previous JSON (--out or --reuse-from) and --dir with "
                  "full.mcap (and incremental.mcap)", file=sys.stderr)
            return 2
        old = json.loads(prev.read_text())
        wall, cpu, tap = old["wall_s"], old.get("cpu_s", {}), old.get("tap_cpu_s", {})
        if a.reuse_from:
            _run([f"nodes={a.nodes}", f"hosts={a.hosts}", "duration=0.5", "warmup=0.1"],
                 a.method, d / "warm.mcap")
            wall["incremental"], cpu["incremental"], tap["incremental"] = _run(
                inc_sets, a.method, inc)
    else:
        _run([f"nodes={a.nodes}", f"hosts={a.hosts}", "duration=0.5", "warmup=0.1"], a.method,
             d / "warm.mcap")
        runs = {"plain": _run(base, a.method, None), "full": _run(base, a.method, full),
                "incremental": _run(inc_sets, a.method, inc)}
        wall = {k: v[0] for k, v in runs.items()}
        cpu = {k: v[1] for k, v in runs.items()}
        tap = {k: v[2] for k, v in runs.items() if k != "plain"}
    size = {"full": full.stat().st_size, "incremental": inc.stat().st_size}
    runs = open_recording(inc).runs[a.method]
    res: dict[str, object] = {
        "nodes": a.nodes, "duration_s": a.duration, "method": a.method,
        "deadband": {"pos_m": a.deadband_pos, "vel_mps": a.deadband_vel,
                     "att_rad": a.deadband_att, "keyframe_every": a.keyframe_every},
        "wall_s": wall, "cpu_s": cpu, "tap_cpu_s": tap,
        "overhead": {k: wall[k] / wall["plain"] - 1 for k in ("full", "incremental")},
        "recorder_cpu_s": {k: cpu[k] - cpu["plain"] for k in ("full", "incremental") if cpu},
        "bytes": size, "size_ratio": size["full"] / size["incremental"],
        "states": int(runs["states"]), "states_stored": int(runs["states_stored"]),
        "load_avg_1min": os.getloadavg()[0], "cpus": os.cpu_count(),
    }
    if not a.no_replay:
        res["reconstruction"] = reconstruction_error(full, inc, a.method)
        t0, c0 = time.perf_counter(), time.process_time()
        df = replay(inc, a.rate, "hermite-dw")
        t_replay, c_replay = time.perf_counter() - t0, time.process_time() - c0
        t0 = time.perf_counter()
        df.to_csv(d / "traj.csv", index=False)
        res["replay"] = {"rate_hz": a.rate, "rows": len(df), "read_and_rebuild_s": t_replay,
                         "read_and_rebuild_cpu_s": c_replay,
                         "csv_write_s": time.perf_counter() - t0}
    text = json.dumps(res, indent=2)
    print(text)
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
