"""Trigger times come from a grid ``t0 + (k - k0) / f``, never a running sum (issue 9.1)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sigma_des import load
from sigma_des.events.cohort import execute
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny

ISSUE = [
    "nodes=1",
    "hosts=1",
    "duration=3",
    "warmup=0.5",
    "dynamics=pointmass",
    "commands.enabled=false",
    "fidelity.enabled=false",
]


def _run(sc, method):  # type: ignore[no-untyped-def]
    return execute(sc.run_spec(), method, lambda: make_dynamics(sc), lambda: make_behaviour(sc))


@pytest.mark.parametrize("engine", ["events", "cohort"])
@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_trigger_rate_is_exactly_f_trig(engine: str, method: str) -> None:
    """The issue's case: 1 node, 2.5 s window at 100 Hz is 250 triggers, for every method."""
    sc = replace(load(None, ISSUE), engine=engine)
    run, out, _ = _run(sc, method)
    assert out["metrics"]["trigger_rate_hz"] == 100.0
    assert run.latest_trigger == 299  # triggers 0..299 at k/100 < 3 s


@pytest.mark.parametrize("engine", ["events", "cohort"])
def test_lockstep_trigger_times_are_multiplied(engine: str) -> None:
    """Every on-time Lock-Step trigger k sits bit-exactly at k / f_trig."""
    sc = tiny(engine=engine, history_frames=64)
    run, _, _ = _run(sc, "lockstep")
    k = np.arange(run.latest_trigger - 63, run.latest_trigger + 1)
    np.testing.assert_array_equal(run.trigger.trig_time[k % run.trigger.H], k / 100.0)
