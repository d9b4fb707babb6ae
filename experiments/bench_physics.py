"""Cost of one physics frame step (dt = 0.01 s, 100 Hz) per dynamics model.

For 1 000 and 10 000 aircraft: the vectorised step (autopilot + mean wind +
Dryden turbulence inside), the sensor read (IMU, magnetometer, baro, GPS) and
their sum, at each model's default internal sub-step (quadrotor 5 ms, fixed wing
10 ms) and at half of it; the point mass for reference; and JSBSim nodes per
aircraft per step. Figures are the best of several batches, on one core, timed
with the benchmarking thread's CPU time (``time.thread_time``) so that time the
thread spends descheduled on a shared machine does not count (``--wall``: wall
time instead).

``--before REF`` also measures the aircraft step of the package at git revision
``REF`` (exported to a temporary directory and run in a child process, the two
alternating ``--rounds`` times), prints before / after per aircraft type, and
checks that both give the same states bit for bit on the benchmark's inputs
(exit status 1 if not).

Usage: ``python experiments/bench_physics.py [--quick] [--before REF] [--rounds R]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from sigma_des.agents.aircraft import GeneralAircraft  # noqa: E402
from sigma_des.agents.pointmass import PointMass  # noqa: E402
from sigma_des.agents.sensors import Sensors  # noqa: E402
from sigma_des.agents.wind import WindConfig  # noqa: E402

DT = 0.01
ROOT = Path(__file__).resolve().parents[1]

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


def aircraft_case(name: str, n: int, substep: float
                  ) -> tuple[GeneralAircraft, np.ndarray, np.ndarray, np.ndarray]:
    """The benchmarked model, start state, command and node ids (also the identity inputs)."""
    m = GeneralAircraft(name, wind=WindConfig(mean_ned=(3.0, 1.0, 0.0), decay_tau=600.0,
                                              w20=7.7), max_substep=substep)
    s = m.initial_state(n)
    return m, s, m.default_command(s), np.arange(n, dtype=np.int64)


def bench_aircraft(name: str, n: int, substep: float, batches: int) -> tuple[float, float]:
    m, s, cmd, nodes = aircraft_case(name, n, substep)
    sen = Sensors(m, seed=1)
    reps = max(2, 20000 // n)
    step = best_ms(lambda k: m.step(s, cmd, DT, k, nodes), reps, batches)
    read = best_ms(lambda k: sen.read(s, nodes, k), reps, batches)
    return step, read


def identity_states(n: int = 300, frames: int = 30) -> dict[str, np.ndarray]:
    """States of every aircraft case flown ``frames`` frames (turbulence updates included)."""
    out = {}
    for name, subs in SUBSTEPS.items():
        for sub in subs:
            m, s, cmd, nodes = aircraft_case(name, n, sub)
            cmd[::3, 1] += 0.3
            cmd[::5, 3] = 0.1
            for f in range(1, frames + 1):
                s = m.step(s, cmd, DT, f, nodes)
            out[f"{name}_{sub}"] = s
    return out


def step_costs(batches: int) -> dict[str, float]:
    """Aircraft step cost (ms) per ``model/substep/n`` key (no sensors)."""
    res = {}
    for name, subs in SUBSTEPS.items():
        for sub in subs:
            for n in (1000, 10000):
                m, s, cmd, nodes = aircraft_case(name, n, sub)
                reps = max(2, 20000 // n)
                res[f"{name} h={sub * 1e3:g}ms {n}"] = best_ms(
                    lambda k, m=m, s=s, c=cmd, nd=nodes: m.step(s, c, DT, k, nd), reps, batches)
    return res


def run_child(src: Path, batches: int, out: Path) -> dict[str, float]:
    """This script's ``--child`` mode with ``src`` first on the path (returns its costs)."""
    env = dict(os.environ, PYTHONPATH=str(src))
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", str(out),
                    "--batches", str(batches)], env=env, check=True, cwd=src)
    return json.loads(out.with_suffix(".json").read_text())


def export_tree(ref: str, dest: Path) -> Path:
    """The ``sigma_des`` package at git revision ``ref``, unpacked under ``dest``."""
    tar = dest / "src.tar"
    with tar.open("wb") as fh:
        subprocess.run(["git", "-C", str(ROOT), "archive", ref, "sigma_des"], stdout=fh,
                       check=True)
    with tarfile.open(tar) as tf:
        tf.extractall(dest / "src", filter="data")
    return dest / "src"


def before_after(ref: str, batches: int, rounds: int) -> int:
    """Alternate the package at ``ref`` and this tree; print both; 1 if states differ."""
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        old = export_tree(ref, tmpd)
        runs: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
        for r in range(rounds):
            runs["before"].append(run_child(old, batches, tmpd / f"before{r}"))
            runs["after"].append(run_child(ROOT, batches, tmpd / f"after{r}"))
        a = np.load(tmpd / "before0.npz")
        b = np.load(tmpd / "after0.npz")
        same = all(np.array_equal(a[k].view(np.uint64), b[k].view(np.uint64)) for k in a.files)
    print(f"\nbefore ({ref}) / after (this tree): aircraft step, ms per frame, best of "
          f"{rounds} alternating rounds x {batches} batches (thread CPU time)")
    print(f"{'case':<30}{'before':>9}{'after':>9}{'speed-up':>10}{'after /1000':>13}")
    for key in runs["after"][0]:
        bef = min(r[key] for r in runs["before"])
        aft = min(r[key] for r in runs["after"])
        n = int(key.split()[-1])
        print(f"{key:<30}{bef:>9.3f}{aft:>9.3f}{bef / aft:>9.2f}x{aft / n * 1e3:>13.3f}")
    print(f"states after 30 frames (300 aircraft, every case): "
          f"{'bit-identical' if same else 'DIFFERENT'}")
    return 0 if same else 1


def main_table(batches: int, quick: bool, wall: bool) -> None:
    clock = "wall" if wall else "thread CPU"
    print(f"one frame step, dt = {DT} s (100 Hz), one core, best of {batches} batches "
          f"({clock} time); load average {os.getloadavg()[0]:.1f}")
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
        ms = bench_jsbsim(model, 50 if quick else 200)
        if ms is not None:
            print(f"{'jsbsim:' + model:<22}{'1':>7}{ms:>10.3f}{'-':>12}{ms:>10.3f}"
                  f"{ms * 1e3:>13.1f}   (per aircraft, FDM at 400 Hz)")


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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer batches")
    ap.add_argument("--wall", action="store_true", help="time with the wall clock")
    ap.add_argument("--before", metavar="REF", help="also measure the package at git REF")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds for --before")
    ap.add_argument("--batches", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    global CLOCK
    if args.wall:
        CLOCK = time.perf_counter
    batches = args.batches or (3 if args.quick else 20)
    if args.child is not None:
        args.child.with_suffix(".json").write_text(json.dumps(step_costs(batches)))
        np.savez(args.child.with_suffix(".npz"), **identity_states())
        return 0
    main_table(batches, args.quick, args.wall)
    if args.before:
        return before_after(args.before, batches, max(1, args.rounds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
