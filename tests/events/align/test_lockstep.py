"""The Lock-Step barrier's counting (events/align/lockstep.py), by hand and against the
row-by-row rule it compiles."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.events.align.base import OBS_WIDTH, StateBatch
from sigma_des.events.align.lockstep import LockstepAligner
from sigma_des.events.align.spec import LockstepSpec


class Ctx:
    """The engine's side: records timers and barriers; opens the next barrier at once
    when ``chain`` (as the engine issues trigger k+1 on barrier k)."""

    def __init__(self, chain: bool = False) -> None:
        self.t = 0.0
        self.timers: list[tuple[float, Any, tuple[Any, ...]]] = []
        self.done: list[int] = []
        self.chain = chain
        self.al: LockstepAligner | None = None

    def latest_trigger(self) -> int:
        return self.done[-1] + 1 if self.done else 0

    def f_trig(self) -> float:
        return 100.0

    def now(self) -> float:
        return self.t

    def call_at(self, t: float, fn: Any, *args: Any) -> None:
        self.timers.append((t, fn, args))

    def set_rate(self, f_trig: float) -> None:
        pass

    def barrier_done(self, frame: int) -> None:
        self.done.append(frame)
        if self.chain and self.al is not None:
            self.al.on_trigger(frame + 1, self.t)

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        pass


def _aligner(n: int, chain: bool = False, evict: float = 0.0) -> tuple[LockstepAligner, Ctx]:
    ctx = Ctx(chain)
    al = LockstepAligner(n, LockstepSpec(retry_timeout=0.05, eviction_timeout=evict), ctx)
    ctx.al = al
    return al, ctx


def _batch(rows: list[tuple[int, int]], gen0: float = 0.0) -> StateBatch:
    nodes = np.array([r[0] for r in rows], dtype=np.int64)
    frames = np.array([r[1] for r in rows], dtype=np.int64)
    gens = gen0 + np.arange(len(rows), dtype=np.float64) / 1000.0
    obs = np.arange(len(rows) * OBS_WIDTH, dtype=np.float64).reshape(len(rows), OBS_WIDTH)
    m = len(rows)
    return StateBatch(t=gens.copy(), nodes=nodes, frames=frames, gens=gens, obs=obs,
                      hlc_l=np.full(m, np.nan), hlc_c=np.zeros(m, dtype=np.int64))


def test_a_barrier_completes_on_its_last_missing_state_once() -> None:
    """Three nodes, frame 0: node 1 twice (the second is not counted), a stale frame,
    then node 2 completes it at row 4; the row after it changes nothing."""
    al, ctx = _aligner(3)
    al.on_trigger(0, 0.0)
    b = _batch([(0, 0), (1, 0), (1, 0), (2, -1), (2, 0), (0, 0)])
    al.on_states(b)
    assert ctx.done == [0] and al.complete and al.missing == 0
    assert al.got.tolist() == [True, True, True]
    assert al.barrier().complete
    # the stored states are the first counted rows: 0, 1 and 4
    al.align(0.01)
    assert al.shown_gen.tolist() == [0.0, 0.001, 0.004]
    assert al.shown_obs[2].tolist() == b.obs[4].tolist()


def test_rows_after_a_completion_count_for_the_barrier_the_engine_opened() -> None:
    """The engine opens frame 1 inside barrier_done: the batch's later rows of frame 1
    count for it, and complete it too."""
    al, ctx = _aligner(2, chain=True)
    al.on_trigger(0, 0.0)
    al.on_states(_batch([(0, 0), (0, 1), (1, 0), (1, 1), (0, 1)]))
    assert ctx.done == [0, 1]
    assert al.current == 2 and not al.complete and al.missing == 2  # chain opened 2


def test_an_evicted_node_rejoins_when_it_delivers_the_newest_frame() -> None:
    al, ctx = _aligner(3, evict=0.2)
    al.on_trigger(0, 0.0)
    al.on_states(_batch([(0, 0), (1, 0)]))
    evict = next(fn for _t, fn, _a in ctx.timers if fn.__name__ == "_evict")
    evict(0)  # the engine's timer: node 2 still missing at the eviction timeout
    assert ctx.done == [0] and al.evicted == 1 and not al.live[2]
    al.on_trigger(1, 0.01)
    assert al.missing == 2
    al.on_states(_batch([(2, 0), (2, 1), (0, 1)]))  # its old frame: not back; frame 1: back
    assert al.rejoined == 1 and al.live[2] and al.missing == 1
    al.on_states(_batch([(1, 1)]))
    assert ctx.done == [0, 1]


def _reference(al: dict[str, Any], rows: list[tuple[int, int]], done: list[int],
               chain: bool) -> None:
    """The row-by-row rule the compiled loop replaces (session 13's on_states)."""
    for node, frame in rows:
        if not al["live"][node] and frame == al["current"]:
            al["live"][node] = True
            al["rejoined"] += 1
            al["missing"] += 1
        if frame != al["current"] or al["complete"] or al["got"][node]:
            continue
        al["missing"] -= 1
        al["got"][node] = True
        if al["missing"] <= 0:
            al["complete"] = True
            done.append(al["current"])
            if chain:
                al["current"] += 1
                al["complete"] = False
                al["got"][:] = False
                al["missing"] = int(al["live"].sum())


@pytest.mark.parametrize("seed", range(40))
def test_the_compiled_count_is_the_row_by_row_rule(seed: int) -> None:
    """Random batches of random nodes and frames around the current one, some nodes
    evicted first: the same completions, counters and flags as the rule row by row."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    chain = bool(rng.integers(2))
    al, ctx = _aligner(n, chain=chain)
    al.on_trigger(0, 0.0)
    al.live[:] = rng.random(n) > 0.3
    al.missing = int(al.live.sum())
    ref = {"live": al.live.copy(), "got": al.got.copy(), "current": 0, "complete": False,
           "missing": al.missing, "rejoined": 0}
    done: list[int] = []
    for _ in range(6):
        cur = al.current
        rows = [(int(rng.integers(n)), int(cur + rng.integers(-1, 3))) for _ in
                range(int(rng.integers(0, 3 * n + 1)))]
        al.on_states(_batch(rows))
        _reference(ref, rows, done, chain)
        if not chain and al.complete and rng.random() < 0.5:
            al.on_trigger(cur + 1, 0.0)
            ref.update(current=cur + 1, complete=False, missing=int(ref["live"].sum()))
            ref["got"][:] = False
        assert ctx.done == done
        assert (al.current, al.complete, al.missing, al.rejoined) == (
            ref["current"], ref["complete"], ref["missing"], ref["rejoined"])
        assert al.live.tolist() == ref["live"].tolist()
        assert al.got.tolist() == ref["got"].tolist()
