"""``run_method`` leaves nothing of a finished run behind in the process.

A run's parts call each other back, so a finished run is cyclic garbage; left to the
automatic collections it lingered for many runs (with its rings, samples and tables)
when a sweep or ``compare`` ran one method after another in a process. ``run_method``
collects the young generations once it is done with the run.
"""

from __future__ import annotations

import gc

from sigma_des.api import run_method
from sigma_des.events.engine import MethodRun
from tests.conftest import tiny


def _alive() -> int:
    return sum(isinstance(o, MethodRun) for o in gc.get_objects())


def test_finished_runs_do_not_linger() -> None:
    sc = tiny(**{"commands.enabled": True, "commands.behaviour": "follow"})
    run_method(sc, "bides")  # imports and first-use caches out of the count
    before = _alive()
    outs = [run_method(sc, m) for m in ("bides", "none", "hlc")]
    # every run freed (one may be left to a full collection if an automatic collection
    # moved it to the oldest generation while it was still in use: without the young
    # collection all three stay)
    assert _alive() - before <= 1
    assert all(o["metrics"]["aoi_mean"] > 0 for o in outs)
