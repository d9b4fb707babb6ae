"""A finished run lets its truth's rings go, and nothing it reports changes.

``MethodRun.run`` releases the truth (``SwarmTruth.release``) once the results are
assembled: the frames still in the ring enter the fidelity log and the rings are
dropped, so a finished run that lingers as cyclic garbage no longer holds them. The
trajectory and every result must be those of the same run kept whole.
"""

from __future__ import annotations

import gc
import weakref
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.events.cohort import make_run
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny


def _scenario(engine: str) -> Any:
    # a ring of 16 frames over 100 frames: most frames enter the log when overwritten,
    # the last 16 only at the end (release, or trajectory() on a run kept whole)
    sc = tiny(**{"history_frames": 16, "commands.enabled": True,
                 "commands.behaviour": "follow", "commands.every": 2,
                 "net.host_link.latency": 0.004})
    return replace(sc, engine=engine)


def _kept_whole(sc: Any, method: str) -> tuple[Any, dict[str, Any]]:
    """The run driven as ``run()`` does, without the release at its end."""
    run, _ = make_run(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc))
    run.start()
    gc.disable()
    try:
        run.advance(None)
    finally:
        gc.enable()
    run.core.close()
    return run, run.finish()


@pytest.mark.parametrize("engine", ["events", "cohort"])
@pytest.mark.parametrize("method", ["none", "bides"])
def test_released_run_reports_what_the_whole_run_reports(engine: str, method: str) -> None:
    sc = _scenario(engine)
    whole, ref = _kept_whole(sc, method)
    assert whole.truth.ckpt.shape[0] == (16 if method == "bides" else 0)
    run, _ = make_run(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc))
    out = run.run()
    assert run.truth.released and not whole.truth.released
    assert run.latest_trigger == whole.latest_trigger >= 90  # the ring wrapped
    for key, value in ref["metrics"].items():
        v = out["metrics"][key]
        assert (np.isnan(value) and np.isnan(v)) or value == v, key
    t_ref, pos_ref = whole.trajectory()
    for _ in range(2):  # the log is complete and stays so
        t, pos = run.trajectory()
        np.testing.assert_array_equal(t, t_ref)
        np.testing.assert_array_equal(pos, pos_ref)
    # the frames the ring held at the end are logged: up to the last frame's time
    assert t[-1] > 1.0 - 1.0 / sc.fidelity.log_rate
    np.testing.assert_array_equal(run.state, whole.state)


@pytest.mark.parametrize("engine", ["events", "cohort"])
def test_a_finished_run_no_longer_holds_its_rings(engine: str) -> None:
    sc = _scenario(engine)
    run, _ = make_run(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    rings = [weakref.ref(run.truth.ckpt), weakref.ref(run.truth.obs_hist)]
    assert run.truth.ckpt.size and run.truth.obs_hist.size
    run.run()
    # the run object is alive, its rings are gone (the compiled core let go of the
    # published-state ring it shared)
    assert [r() for r in rings] == [None, None]
    assert run.truth.ckpt.shape == (0, *run.state.shape)
    assert run.truth.obs_hist.shape == (0, 3, 12)
    latest = run.latest_trigger
    assert not run.truth.held(latest)
    assert run.truth_positions(latest) is None
    with pytest.raises(RuntimeError, match="released"):
        run.truth.step_frame(latest + 1, 0.01, run.nodes.cmd, None)
    t, pos = run.trajectory()
    run.truth.release()  # a second release changes nothing
    np.testing.assert_array_equal(run.truth.trajectory()[1], pos)
    assert t.size == pos.shape[0] > 1
