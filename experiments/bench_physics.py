"""Cost of one physics frame step (dt = 0.01 s, 100 Hz) per dynamics model.

For 1 000 and 10 000 aircraft: the vectorised step (autopilot + mean wind +
Dryden turbulence inside), the sensor read (IMU, magnetometer, baro, GPS) and
their sum, at each model's default internal sub-step (quadrotor 5 ms, fixed wing
10 ms) and at half of it; the point mass for reference; and JSBSim nodes per
aircraft per step. Figures are the best of several batches, on one core, timed
with the benchmarking thread's CPU time (``time.thread_time``) so that time the
thread spends descheduled on a shared machine does not count (``--wall``: wall
time instead).

Usage: ``python experiments/bench_physics.py [--quick]``
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from sigma_des.agents.aircraft import GeneralAircraft  # noqa: E402
from sigma_des.agents.pointmass import PointMass  # noqa: E402
from sigma_des.agents.sensors import Sensors  # noqa: E402
from sigma_des.agents.wind import WindConfig  # noqa: E402

DT = 0.01


CLOCK: Callable[[], float] = time.thread_time
#: Internal sub-steps benchmarked per model: the preset default first.
SUBSTEPS = {"quadrotor": (0.005, 0.0025), "fixedwing": (0.01, 0.005)}


def best_ms(fn: Callable[[int], object], reps: int, batches: int) -> float:
    """Best mean time (ms, :data:`CLOCK`) of ``reps`` calls over ``batches`` batches."""
    fn(0)
    best = float("inf")
    k = 1
    for _ in range(batches):
        t = CLOCK()
        for _ in range(reps):
            fn(k)
            k += 1
        best = min(best, (CLOCK() - t) / reps * 1e3)
    return best


def bench_aircraft(name: str, n: int, substep: float, batches: int) -> tuple[float, float]:
    m = GeneralAircraft(name, wind=WindConfig(mean_ned=(3.0, 1.0, 0.0), decay_tau=600.0,
                                              w20=7.7), max_substep=substep)
    sen = Sensors(m, seed=1)
    s = m.initial_state(n)
    cmd = m.default_command(s)
    nodes = np.arange(n, dtype=np.int64)
    reps = max(2, 20000 // n)
    step = best_ms(lambda k: m.step(s, cmd, DT, k, nodes), reps, batches)
    read = best_ms(lambda k: sen.read(s, nodes, k), reps, batches)
    return step, read


def bench_jsbsim(model: str, steps: int) -> float | None:
    try:
        from sigma_des.agents.jsbsim_node import JSBSimModel
    except ImportError:
        return None
    m = JSBSimModel(model)
    s = m.initial_state(4)
    cmd = m.default_command(s)
    nodes = np.arange(4, dtype=np.int64)
    s = m.step(s, cmd, DT, 1, nodes)
    t = time.perf_counter()
    for k in range(2, steps + 2):
        s = m.step(s, cmd, DT, k, nodes)
    return (time.perf_counter() - t) / steps / 4 * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer batches")
    ap.add_argument("--wall", action="store_true", help="time with the wall clock")
    args = ap.parse_args()
    global CLOCK
    if args.wall:
        CLOCK = time.perf_counter
    batches = 3 if args.quick else 20
    clock = "wall" if args.wall else "thread CPU"
    print(f"one frame step, dt = {DT} s (100 Hz), one core, best of {batches} batches "
          f"({clock} time)")
    print(f"{'model':<22}{'n':>7}{'step ms':>10}{'sensors ms':>12}{'total ms':>10}"
          f"{'us/aircraft':>13}")
    for name in ("quadrotor", "fixedwing"):
        for sub in SUBSTEPS[name]:
            for n in (1000, 10000):
                st, rd = bench_aircraft(name, n, sub, batches)
                label = f"{name} h={sub * 1e3:g}ms"
                print(f"{label:<22}{n:>7}{st:>10.3f}{rd:>12.3f}{st + rd:>10.3f}"
                      f"{(st + rd) / n * 1e3:>13.3f}")
    pm = PointMass()
    for n in (1000, 10000):
        s = pm.initial_state(n)
        c = pm.default_command(s)
        nodes = np.arange(n)
        st = best_ms(lambda k, s=s, c=c, nodes=nodes: pm.step(s, c, DT, k, nodes), 50, batches)
        print(f"{'pointmass':<22}{n:>7}{st:>10.3f}{'-':>12}{st:>10.3f}{st / n * 1e3:>13.3f}")
    for model in ("F450", "c172x"):
        ms = bench_jsbsim(model, 50 if args.quick else 200)
        if ms is not None:
            print(f"{'jsbsim:' + model:<22}{'1':>7}{ms:>10.3f}{'-':>12}{ms:>10.3f}"
                  f"{ms * 1e3:>13.1f}   (per aircraft, FDM at 400 Hz)")


if __name__ == "__main__":
    main()
