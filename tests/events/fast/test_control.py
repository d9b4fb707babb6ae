"""The compiled control loop (events/fast/control.py) gives the SimPy path's bits.

A BiDES run on the delay study's configuration (200 ms links, 10 % loss: late commands
roll nodes back, the rate adapts, frame draws run out of their block) is advanced to its
end by :class:`CompiledControl` and by ``MethodRun.advance_until`` on the kernel; the
truth's rings, the aligner's ring and snapshot, the trigger source and every counter
must be equal bit for bit. At the env's level, episodes of the study's env with the
loop equal those of the per-message engine (the executable specification).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.config import load
from sigma_des.core.models import SwarmView
from sigma_des.env import SwarmVec
from sigma_des.events.align.bides import BidesAligner
from sigma_des.events.cohort import make_run
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import control as C
from sigma_des.events.fast.control_run import END, CompiledControl, unsupported
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.factory import make_dynamics
from tests.env.nested import flat_arrays

STUDY: dict[str, Any] = {"nodes": 5, "dynamics": "pointmass",
         "net.host_link.latency": {"dist": "normal", "mean": 0.2, "std": 0.04},
         "net.host_link.loss": {"p": 0.1}}


class _Steer:
    """A behaviour turning every node a little at each command tick (commands that
    arrive late make the nodes roll back); records the views it was shown."""

    name = "steer"

    def __init__(self) -> None:
        self.views: list[bytes] = []

    def commands(self, view: SwarmView, dynamics: Any) -> np.ndarray:
        self.views.append(view.obs.tobytes() + view.frame.tobytes()
                          + np.array([view.aligned_frame]).tobytes())
        n = view.obs.shape[0]
        k = len(self.views)
        return np.column_stack([np.full(n, 10.0 + k % 3), np.full(n, (k % 5) - 2.0),
                                np.zeros(n)])


def _run(seed: int, duration: float, method: str = "bides") -> tuple[MethodRun, _Steer]:
    sc = load(**{**STUDY, "seed": seed, "duration": duration, "warmup": 0.0})
    steer = _Steer()
    run = make_run(sc.run_spec(), method, make_dynamics(sc), steer, False)[0]
    run.start()
    return run, steer


def _state(run: MethodRun, steer: _Steer) -> list[Any]:
    al = run.aligner
    t = run.truth
    held = t.slot_frame >= 0  # the rings' other slots were never written (np.empty)
    ckpt = t.ckpt[held] if t.ckpt.shape[0] else t.ckpt  # none: no checkpoints
    return [ckpt, t.obs_hist[held], t.slot_frame, t.frame_dt, t.phys_hist, t.state,
            np.array([t.latest, t.rollbacks, t.resim_steps, t.phys_t]),
            run.trigger.trig_time, np.array([run.trigger.latest, run.trigger.f_trig]),
            np.array(run.trigger.base), al.shown_frame, al.shown_gen, al.shown_obs, al.flag,
            np.array([al.aligned_frame, al.new_snapshot, al.peak_bytes, run.align_tick]),
            *((al.ring.frame, al.ring.gen_time, al.ring.obs, al.ring.latest,
               np.array([al.rate_changes])) if isinstance(al, BidesAligner) else ()),
            run.nodes.cmd, np.array([run.kernel.now]), steer.views]


def _same(a: list[Any], b: list[Any]) -> None:
    for j, (x, y) in enumerate(zip(flat_arrays(a), flat_arrays(b), strict=True)):
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape, j
            assert x.tobytes() == y.tobytes(), j
        else:
            assert x == y, j


@pytest.mark.parametrize("seed", [1, 2])
def test_a_run_in_the_loop_equals_the_run_on_the_kernel(seed: int) -> None:
    ref, ref_steer = _run(seed, 6.0)
    ref.advance(None)  # the run loop on the kernel (messages first at equal times)
    run, steer = _run(seed, 6.0)
    ctl = CompiledControl(run)
    assert ctl.advance_until(lambda: False) == END
    _same(_state(run, steer), _state(ref, ref_steer))
    rolled = [r.core.exit_counts()["NEED_ROLLBACK"] for r in (run, ref)
              if isinstance(r.core, CompiledCore)]
    assert rolled[0] == rolled[1] == run.truth.rollbacks
    # the paths the test is about were taken: rollbacks served in the loop (and a job
    # start handed to Python), the rate adapted, frame draws sampled again, commands
    assert run.truth.rollbacks > 0 and ctl.ci[C.CI_RATE_CHANGES] > 0
    assert ctl.returns.get(C.START, 0) > 0 and ctl.returns.get(C.DRAWS, 0) > 0
    assert len(steer.views) > 20


def test_a_none_run_in_the_loop_equals_the_run_on_the_kernel() -> None:
    ref, ref_steer = _run(5, 4.0, "none")
    ref.advance(None)
    run, steer = _run(5, 4.0, "none")
    ctl = CompiledControl(run)
    assert ctl.advance_until(lambda: False) == END
    assert run.truth.ckpt.shape[0] == 0  # no checkpoints without time warp: a scratch step
    _same(_state(run, steer), _state(ref, ref_steer))
    assert len(steer.views) > 20


def test_pausing_at_every_command_tick_changes_nothing() -> None:
    ref, ref_steer = _run(3, 3.0)
    ref.advance(None)  # the run loop on the kernel (messages first at equal times)
    run, steer = _run(3, 3.0)
    ctl = CompiledControl(run)
    pauses = 0
    while ctl.advance_until(lambda: True) != END:
        pauses += 1
    assert pauses == len(steer.views) > 10
    _same(_state(run, steer), _state(ref, ref_steer))


@pytest.mark.parametrize("method", ["bides", "none"])
def test_the_study_env_in_the_loop_equals_the_per_message_engine(method: str) -> None:
    def play(engine: str) -> list[Any]:
        env = SwarmVec(task="tight", method=method, n_scenes=3, max_steps=6, metrics=False,
                       scenario={**STUDY, "engine": engine})
        out: list[Any] = list(env.reset(seed=4))
        rng = np.random.default_rng(4)
        for _ in range(16):
            out += list(env.step(rng.uniform(-1.0, 1.0, (3, env.n_agents, 3))))
        looped = [sc.control is not None for sc in env.batch.scenes]
        assert looped == [engine == "cohort"] * 3
        return out

    _same(play("cohort"), play("events"))


def test_what_the_loop_does_not_cover_is_said() -> None:
    sc = load(**{**STUDY, "duration": 1.0})
    for method, metrics, why in [("hlc", False, "method 'hlc'"),
                                 ("bides", True, "collects metrics")]:
        run = make_run(sc.run_spec(), method, make_dynamics(sc), None, metrics)[0]
        run.start()
        reason = unsupported(run)
        assert reason is not None and why in reason
        with pytest.raises(ValueError, match="compiled control"):
            CompiledControl(run)
    run = make_run(sc.run_spec(), "bides", make_dynamics(sc), None, False)[0]
    run.start()
    assert unsupported(run) is None
    run.kernel.at(0.5, print)  # an event the loop does not run: the kernel's path
    reason = unsupported(run)
    assert reason is not None and "other events" in reason
    events = load(**{**STUDY, "duration": 1.0, "engine": "events"})
    run = make_run(events.run_spec(), "bides", make_dynamics(events), None, False)[0]
    assert unsupported(run) == "the run is not on the compiled core"


def test_the_physics_kernels_keep_one_identity_across_processes() -> None:
    """The loop's cached overloads are keyed by the kernels' dispatcher types, pickled by
    the dispatcher's uuid: a uuid fixed by the kernel's name (not drawn per process)
    makes a key loaded from the cache name the live kernel (a hit, and no stand-in
    dispatcher that dies before the cache index is written again)."""
    import pickle
    import uuid

    from numba.core.serialize import dumps

    run, _ = _run(1, 0.5)
    CompiledControl(run)
    for kernel in run.dyn.compiled_physics()[:3]:
        fn = kernel.py_func
        name = f"sigma_des.kernel:{fn.__module__}.{fn.__qualname__}"
        assert kernel._uuid == str(uuid.uuid5(uuid.NAMESPACE_URL, name))
        assert pickle.loads(dumps(kernel)) is kernel  # numba's own pickling: the live one
