#!/usr/bin/env python
"""Cost of one GA generation, batched (one flight of P aircraft) vs candidate by candidate.

A generation scores P parameter sets on a 10 s log at 50 Hz cut into 1 s windows.
*Batched* is the tuning path (sigma_des/tuning/replay.py): one compiled call flies
every (candidate, window) row, one compiled call computes every DTW. *One by one*
replays each candidate alone through ``GeneralAircraft.step_open_loop`` (one
Python call per step, all windows of that candidate as rows) and scores it with
the same fitness; both give identical numbers (tested). Printed: ms per
generation, generations/s and the speed-up, per aircraft kind and P; plus a
full GA run's generations/s. Timing uses the thread's CPU time (best of
several repetitions).

Usage: ``python experiments/bench_tuning.py [--quick]``
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from sigma_des.agents.presets import preset  # noqa: E402
from sigma_des.tuning.fitness import fitness  # noqa: E402
from sigma_des.tuning.flightlog import resample  # noqa: E402
from sigma_des.tuning.ga import Evaluator, tune  # noqa: E402
from sigma_des.tuning.replay import replay_serial, windows  # noqa: E402
from sigma_des.tuning.spec import TuneSpec, bounds  # noqa: E402
from sigma_des.tuning.synth import fly  # noqa: E402


def best_s(fn: object, reps: int) -> float:
    """Best CPU time (s) of ``reps`` calls."""
    assert callable(fn)
    fn()
    best = float("inf")
    for _ in range(reps):
        t = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t)
    return best


def bench(kind: str, pop: int, duration: float, reps: int) -> tuple[float, float]:
    """(batched, one-by-one) seconds per generation."""
    truth = preset(kind)
    log = fly(truth, kind, duration=duration)
    win = windows(resample(log, 50.0), 1.0)
    spec = TuneSpec(population=pop)
    names, lo, hi = bounds(spec, truth, kind)
    ev = Evaluator(win, truth, names, spec.channels_of(kind), band=spec.band)
    u = np.random.default_rng(0).uniform(size=(pop, len(names)))
    xs = np.array(lo) + u * (np.array(hi) - np.array(lo))

    def serial() -> np.ndarray:
        out = np.empty(pop)
        for i, x in enumerate(xs):
            p = ev.params_of(x)
            assert p is not None
            out[i] = fitness(win, replay_serial(win, p)[None], ev.spec)[0]
        return out

    assert np.array_equal(ev(xs), serial())
    return best_s(lambda: ev(xs), reps), best_s(serial, max(1, reps // 3))


def main() -> int:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test)")
    a = ap.parse_args()
    pops = (8,) if a.quick else (16, 64)
    dur = 2.0 if a.quick else 10.0
    reps = 1 if a.quick else 5
    print(f"{'kind':10s} {'P':>4s} {'batched ms':>11s} {'one-by-one ms':>14s} "
          f"{'gen/s':>7s} {'speed-up':>9s}")
    for kind in ("quadrotor", "fixedwing"):
        for pop in pops:
            b, s = bench(kind, pop, dur, reps)
            print(f"{kind:10s} {pop:4d} {b * 1e3:11.2f} {s * 1e3:14.2f} {1 / b:7.2f} "
                  f"{s / b:9.1f}", flush=True)
    gens = 3 if a.quick else 30
    for kind in ("quadrotor", "fixedwing"):
        truth = preset(kind)
        log = fly(truth, kind, duration=dur)
        spec = TuneSpec(population=pops[-1] if a.quick else 48, generations=gens)
        t = time.perf_counter()
        res = tune(log, truth, spec)
        wall = time.perf_counter() - t
        print(f"GA {kind}: {gens} generations, P = {spec.population}, {res.evaluations} "
              f"evaluations in {wall:.2f} s wall: {gens / wall:.1f} generations/s "
              f"(log {dur:g} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
