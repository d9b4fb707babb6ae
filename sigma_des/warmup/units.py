"""Compile every numba kernel a default run uses into numba's on-disk cache, in parallel.

A fresh install compiles its kernels on first use (about 1.5 CPU-minutes on a 2-core
machine; docs/concepts/engines.md), so the first ``compare``
spends most of a minute before it simulates. ``sigma-des warmup`` (run once after
installing) pays that cost up front and splits it over the CPUs: the kernels fall in
two independent groups of similar size, each compiled in its own process —

* ``core``: the compiled message core (``advance``, the ``publish_*`` entry points),
  the BiDES ring insert and Algorithm 1, the Lock-Step and HLC paths, the learning env's
  compiled control loop: every method of a tiny point-mass scenario with commands, a
  BiDES run with rollbacks, an aircraft truth's held command rows and a few env steps;
* ``physics``: the 6-DoF aircraft step and observation (quadrotor and fixed wing, one
  specialisation), the sensors, wind and atmosphere kernels, the DTW of the fidelity
  metrics and the streamed summaries of spilled samples: a tiny ideal flight of each
  preset.

Each unit runs tiny scenarios, so the argument types (and hence the compiled
specialisations) are those of a run at any size. Compiled code goes to numba's cache
directory for the current sources (:mod:`sigma_des.jitcache`:
``<root>/numba/<fingerprint>``; the workers compute the same one), so later processes
on the same sources load it instead of compiling.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import NamedTuple

__all__ = ["UNITS", "UnitTime", "run_unit", "warm"]


class UnitTime(NamedTuple):
    """What one warm-up unit cost in its process."""

    unit: str
    wall_s: float
    cpu_s: float
    compiled: int


def _core() -> None:
    import numpy as np

    from sigma_des.api import compare
    from sigma_des.config import METHODS, load
    from sigma_des.events.cohort import make_run
    from sigma_des.events.held import HeldCommands
    from sigma_des.factory import make_behaviour, make_dynamics

    sc = load(None, ["nodes=4", "hosts=2", "duration=0.3", "warmup=0.1", "dynamics=\"pointmass\"",
                     "fidelity.enabled=false"])
    compare(sc, METHODS, progress=False)
    # BiDES rollbacks, and every entry point Python calls only now and then (a job start
    # once its rollback draws are filled, a second rollback, ...), for the state's types
    rb = load(None, ["nodes=40", "hosts=4", "duration=1.0", "warmup=0.3", "dynamics=\"pointmass\"",
                     "fidelity.enabled=false", "broker.publish_service=0.0001",
                     "broker.delivery_service=0.00008", "bides.theta_warp=1", "bides.hold_down=1"])
    compare(rb, ["bides"], progress=False)
    make_run(rb.run_spec(), "bides", make_dynamics(rb), make_behaviour(rb))[0].load_kernels()
    # the command rows an aircraft's truth holds (a point mass's truth keeps none)
    HeldCommands(2, 4).stepped(0, np.zeros((2, 4)))
    _env()


def _env() -> None:
    """A learning env's scenes: the compiled control loop (BiDES with rollbacks, none) and
    the formation tasks' compiled observation and reward (tight, formation)."""
    import numpy as np

    from sigma_des.env import SwarmVec

    lossy = {"nodes": 3, "net.host_link.latency": {"dist": "normal", "mean": 0.1, "std": 0.02},
             "net.host_link.loss": {"p": 0.1}}
    for task, method in (("tight", "bides"), ("tight", "none"), ("formation", "none")):
        env = SwarmVec(task=task, method=method, n_scenes=1, max_steps=4, metrics=False,
                       scenario=lossy)
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.zeros((1, env.n_agents, 3)))


def _physics() -> None:
    from sigma_des.api import fly_ideal
    from sigma_des.config import load
    from sigma_des.metrics.fidelity import fidelity

    for dyn in ("quadrotor", "fixedwing"):
        sc = load(None, ["nodes=3", "hosts=1", "duration=0.3", "warmup=0.1",
                         f"dynamics=\"{dyn}\""])
        _t, pos = fly_ideal(sc)
        fidelity(pos, pos[::-1].copy(), 1.0 / sc.fidelity.log_rate, sc.fidelity.dtw_nodes)
    _streamed()


def _streamed() -> None:
    """The collector's summaries of spilled samples (histograms need > CHUNK values)."""
    import numpy as np

    from sigma_des.metrics.samples import Samples
    from sigma_des.metrics.streamed import CHUNK, summarize_store

    s = Samples(spill=CHUNK)
    s.extend(np.linspace(0.0, 1.0, 3 * CHUNK))
    summarize_store(s)


#: The warm-up units, by name, in the order they are started.
UNITS: dict[str, Callable[[], None]] = {"core": _core, "physics": _physics}


def run_unit(name: str) -> UnitTime:
    """Run one unit in this process; ``compiled`` counts the kernels it compiled (not loaded)."""
    from numba.core import event

    if name not in UNITS:
        raise ValueError(f"unknown warm-up unit {name!r}; allowed: {', '.join(UNITS)}")
    w, c = time.perf_counter(), time.process_time()
    with event.install_recorder("numba:compile") as rec:
        UNITS[name]()
    compiled = sum(1 for _ts, ev in rec.buffer if ev.is_start)
    return UnitTime(name, time.perf_counter() - w, time.process_time() - c, compiled)


def warm(jobs: int = 2, units: Sequence[str] | None = None) -> list[UnitTime]:
    """Run the warm-up units, up to ``jobs`` at once, in fresh spawned worker processes.

    With ``jobs`` below the number of units, a worker runs several units in turn.

    Returns:
        One :class:`UnitTime` per unit, in :data:`UNITS` order.
    """
    names = list(UNITS) if units is None else list(units)
    for n in names:
        if n not in UNITS:
            raise ValueError(f"unknown warm-up unit {n!r}; allowed: {', '.join(UNITS)}")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    import multiprocessing as mp

    # spawn: each worker starts from a clean interpreter, as a later command does
    with ProcessPoolExecutor(max_workers=min(jobs, len(names)),
                             mp_context=mp.get_context("spawn")) as pool:
        return list(pool.map(run_unit, names))
