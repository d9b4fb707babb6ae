"""The loop's entry points called without numba's dispatch, on a handle of the state
(fast/entries.py, fast/handle.py): one set per state type, shared by every core and kept
through a growth of the state; a new handle after a growth (arrays resized in place); a
kernel replaced on the module is called as it is; a run through them gives the
dispatched run's results."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from sigma_des.events.cohort import make_run
from sigma_des.events.fast import entries, loop
from sigma_des.events.fast.growth import grow
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny

SC = replace(tiny(**{"nodes": 8, "hosts": 2, "commands.enabled": True,
                     "commands.behaviour": "follow", "commands.every": 1,
                     "net.host_link.latency": 0.03, "bides.theta_warp": 1,
                     "bides.hold_down": 1}), engine="cohort")


def _run() -> Any:
    run, why = make_run(SC.run_spec(), "bides", make_dynamics(SC), make_behaviour(SC))
    assert why == ""
    return run


def test_one_set_of_entry_points_per_state_type() -> None:
    a, b = _run().core, _run().core
    got = entries.bound(a.S)
    assert entries.bound(b.S) is got  # another run's state: the same type
    assert got.advance is not loop.advance  # an entry point, not the dispatcher
    grown = grow(a.S, 4 * a.array("ev_int").shape[0])
    assert grown is not a.S and entries.bound(grown) is got  # grown: the same type


def test_a_replaced_kernel_is_called_as_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    advance = loop.advance

    def counting(S: Any, bound: float, strict: bool) -> int:
        calls.append(1)
        return int(advance(S, bound, strict))

    monkeypatch.setattr(loop, "advance", counting)
    run = _run()
    assert entries.bound(run.core.S).advance is counting
    run.run()
    assert calls


def test_a_run_through_the_entry_points_gives_the_dispatched_results(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    fast = _run().run()
    monkeypatch.setattr(entries, "bound", lambda S: entries.DISPATCHED)
    slow = _run().run()
    assert fast["metrics"]["rollbacks"] > 0  # rollbacks: start and owe_steps were called
    assert fast["metrics"]["latency_command_mean"] > 0  # commands were published
    assert fast["metrics"] == slow["metrics"]


def test_a_growth_holds_the_state_again() -> None:
    """A growth resizes arrays in place (the payload pool keeps its tuple): the entry
    points then take a new handle of the state, with the grown arrays."""
    core = _run().core
    core.load_kernels()  # binds the entry points and a handle of the state
    held = core._arg
    assert entries.bound(core.S).by_handle and held.S is core.S
    pool = core.array("pool").shape[0]
    core.ensure_space(4 * pool)
    assert core.array("pool").shape[0] > pool
    core._entries()
    assert core._arg is not held and core._arg.S is core.S
