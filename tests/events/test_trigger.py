"""The trigger source on its own: the periodic grid, its rebasing, barrier triggers."""

from __future__ import annotations

from sigma_des.core.sim import Kernel
from sigma_des.events.align.hlc_clock import HLC, Stamp
from sigma_des.events.trigger import TriggerSource


def _source(
    barrier: bool, publish: bool = True, hlc: bool = False
) -> tuple[Kernel, TriggerSource, list[tuple[int, float, float]], list[tuple[int, Stamp | None]]]:
    k = Kernel()
    frames: list[tuple[int, float, float]] = []
    sent: list[tuple[int, Stamp | None]] = []

    def on_frame(f: int, t: float, dt: float) -> None:
        frames.append((f, t, dt))

    def pub(f: int, stamp: Stamp | None) -> None:
        sent.append((f, stamp))

    src = TriggerSource(
        k, 100.0, 16, barrier, on_frame, pub if publish else None, HLC() if hlc else None
    )
    return k, src, frames, sent


def test_periodic_grid_and_rebase_on_a_rate_change() -> None:
    k, src, frames, sent = _source(barrier=False)
    src.start()
    k.run(until=0.025)
    assert frames == [(0, 0.0, 0.01), (1, 0.01, 0.01), (2, 0.02, 0.01)]
    assert [f for f, _ in sent] == [0, 1, 2] and all(s is None for _, s in sent)
    src.f_trig = 50.0  # trigger 3 was already scheduled on the old grid (0.03)
    k.run(until=0.1)
    assert frames[3] == (3, 3 / 100, 1 / 50)  # the new rate steps it
    assert frames[4] == (4, 3 / 100 + 1 / 50, 1 / 50)  # the grid counts from trigger 3
    assert frames[5][1] == 3 / 100 + 2 / 50
    assert src.latest == frames[-1][0] and src.trig_time[4] == frames[4][1]
    assert src.next_trigger() == (src.latest + 1, 1 / 50)


def test_barrier_triggers_wait_for_the_frame_and_restart_the_grid_when_late() -> None:
    k, src, frames, _ = _source(barrier=True)
    src.start()
    k.run(until=1.0)
    assert [f for f, _, _ in frames] == [0]  # nothing periodic
    k.at(1.004, src.barrier_done, 0)  # late (the grid point 0.01 is past): at once
    k.run(until=2.0)
    assert frames[1][:2] == (1, 1.004)
    k.at(2.0, src.barrier_done, 1)  # late again: now, and the grid restarts here
    k.at(2.001, src.barrier_done, 2)  # early: waits for the grid point
    k.run(until=3.0)
    assert frames[2][:2] == (2, 2.0)
    assert frames[3][:2] == (3, 2.0 + 1 / 100)


def test_rpc_publishes_nothing_and_hlc_stamps_triggers() -> None:
    k, src, frames, sent = _source(barrier=False, publish=False)
    src.start()
    k.run(until=0.015)
    assert len(frames) == 2 and sent == []
    k, src, frames, sent = _source(barrier=False, hlc=True)
    src.start()
    assert src.due()  # the next event is its issue
    k.run(until=0.015)
    stamps = [s for _, s in sent]
    assert all(s is not None for s in stamps)
    assert stamps[0] is not None and stamps[1] is not None
    assert (stamps[0].l, stamps[1].l) == (0.0, 0.01)
