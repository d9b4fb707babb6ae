"""``CompiledCore.load_kernels`` loads exactly the specialisations a run calls.

Benchmarks call it in their warm-up so that the timed run loads no kernel: that holds
only if the signatures it builds are the very ones a run's calls resolve to. A run
with command publishes and rollbacks (the entry points a tiny warm-up never reaches)
must therefore add no specialisation after it.
"""

from __future__ import annotations

from dataclasses import replace

from sigma_des.events.cohort import make_run
from sigma_des.events.fast import loop
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny

ENTRY_POINTS = (loop.advance, loop.publish_trigger, loop.publish_commands, loop.start,
                loop.roll_back, loop.owe_steps)


def test_loaded_kernels_are_the_ones_a_run_calls() -> None:
    # late commands and a tight warp threshold: BiDES rolls nodes back, and a target's
    # first rollback job goes through Python (driver._start_job -> loop.start); the
    # point-mass model re-simulates in Python (loop.owe_steps)
    sc = replace(tiny(**{"nodes": 12, "hosts": 2, "commands.enabled": True,
                         "commands.behaviour": "follow", "commands.every": 1,
                         "net.host_link.latency": 0.03, "bides.theta_warp": 1,
                         "bides.hold_down": 1}), engine="cohort")
    run, why = make_run(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    assert why == ""
    run.load_kernels()
    held = [len(k.signatures) for k in ENTRY_POINTS]
    assert all(h >= 1 for h in held)
    assert run.load_kernels() == 0  # all there: nothing more to load
    out = run.run()
    assert out["metrics"]["rollbacks"] > 0  # loop.start was called from Python
    assert out["metrics"]["latency_command_mean"] > 0  # commands were published
    assert [len(k.signatures) for k in ENTRY_POINTS] == held


def test_the_per_message_engine_has_no_kernels_to_load() -> None:
    sc = replace(tiny(), engine="events")
    run, _ = make_run(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    assert run.load_kernels() == 0
