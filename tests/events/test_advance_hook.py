"""The env's stepping hook (``advance_until`` + ``pending_state``) changes nothing.

A run driven from outside — paused at every command tick by a behaviour that only
captures the view, the real behaviour's commands then published at the same time,
and every trigger's physics stepped outside and handed in — must give the very
same results as the run itself, on both engines.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.agents.base import DynamicsModel, SwarmView
from sigma_des.events.cohort import make_run
from sigma_des.events.engine import END, PAUSED, TRIGGER_DUE
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny


class _Capture:
    name = "capture"

    def __init__(self) -> None:
        self.view: SwarmView | None = None

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> Any:
        self.view = view
        return np.full((view.obs.shape[0], dynamics.command_dim), np.nan)


def _driven(sc: Any, method: str) -> tuple[Any, dict[str, Any], int, int]:
    cap = _Capture()
    real = make_behaviour(sc)
    dyn = make_dynamics(sc)
    run, _ = make_run(sc, method, make_dynamics(sc), cap)
    run.start()
    pauses = outside = 0
    while True:
        code = run.advance_until(lambda: cap.view is not None)
        if code == END:
            break
        if code == TRIGGER_DUE:
            k, dt = run.next_trigger()
            run.pending_state = dyn.step(run.state, run.cmd, dt, k, run._nodes)
            outside += 1
            continue
        assert code == PAUSED and cap.view is not None
        cmds = real.commands(cap.view, run.dyn)
        ok = np.flatnonzero(~np.isnan(cmds).all(axis=1))
        run._send_command_batch(run.align_tick - 1, cap.view.aligned_frame, ok, cmds)
        cap.view = None
        pauses += 1
    return run, run.finish(), pauses, outside


@pytest.mark.parametrize("engine", ["events", "cohort"])
@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_driven_run_equals_the_run(engine: str, method: str) -> None:
    sc = replace(
        tiny(**{"commands.enabled": True, "commands.behaviour": "follow",
                "commands.every": 2, "net.host_link.latency": 0.004}),
        engine=engine,
    )
    ref_run, _ = make_run(sc, method, make_dynamics(sc), make_behaviour(sc))
    ref = ref_run.run()
    run, out, pauses, outside = _driven(sc, method)
    assert pauses >= 10  # commands were really injected from outside
    assert outside == ref_run.latest_trigger + 1  # every frame was stepped outside
    for key, value in ref["metrics"].items():
        v = out["metrics"][key]
        assert (np.isnan(value) and np.isnan(v)) or value == v, key
    for key, series in ref["timeseries"].items():
        np.testing.assert_array_equal(series, out["timeseries"][key], err_msg=key)
    np.testing.assert_array_equal(ref_run.state, run.state)
    t_ref, pos_ref = ref_run.trajectory()
    t_out, pos_out = run.trajectory()
    np.testing.assert_array_equal(t_ref, t_out)
    np.testing.assert_array_equal(pos_ref, pos_out)
