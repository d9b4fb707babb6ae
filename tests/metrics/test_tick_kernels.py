"""The collector's compiled tick pieces against the numpy code they replace, bit for bit.

``_Reference`` is the numpy code of ``Collector.shown``, ``Collector.render`` and
``AoITracker.update`` before they were compiled (31370a2), copied verbatim onto plain
attributes; the collector is read only through its public results.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from sigma_des.core.flags import EXTRAPOLATED, FILLED
from sigma_des.metrics.aoi import AoITracker
from sigma_des.metrics.collector import Collector, CollectorSpec
from sigma_des.metrics.reports import AlignerReport, NetReport, RunReport
from sigma_des.metrics.streamed import pairwise_sum

Array = np.ndarray


class _Reference:
    """The numpy code of the render tick, the shown states and the AoI update."""

    def __init__(self, n: int, w0: float) -> None:
        self.w0 = w0
        self.shown_gen = np.full(n, np.nan)
        self.gen, self.acc = np.full(n, np.nan), np.full(n, np.nan)
        self.start, self.area = np.full(n, np.nan), np.zeros(n)
        self.peak_sum, self.peak_count = 0.0, 0
        self.ages: list[Array] = []
        self.errs: list[Array] = []
        self.spread: list[int] = []
        self.counts = [0, 0, 0, 0]
        self.mean: list[float] = []
        self.max: list[float] = []

    def shown(self, t: float, gen: Array) -> None:
        changed = np.flatnonzero(~np.isnan(gen) & ~(gen == self.shown_gen))
        if changed.size:
            self.update(t, changed, gen[changed])
            self.shown_gen = gen.copy()

    def update(self, t: float, nd: Array, g: Array) -> None:
        old = self.gen[nd]
        shown = ~np.isnan(old)
        newer = (g > old) | (~shown & ~np.isnan(g))
        if not newer.all():
            nd, g, old, shown = nd[newer], g[newer], old[newer], shown[newer]
        re = nd[shown]
        if re.size:
            g_old = old[shown]
            a = self.acc[re]
            dt = np.maximum(t - a, 0.0)
            self.area[re] += dt * ((t + a) * 0.5 - g_old)
            self.acc[re] = np.maximum(a, t)
            if t >= self.w0:
                self.peak_sum += float(np.sum(t - g_old))
                self.peak_count += int(re.size)
        first = nd[~shown]
        if first.size:
            begin = max(t, self.w0)
            self.acc[first] = begin
            self.start[first] = begin
        self.gen[nd] = g

    def render(self, t: float, gen: Array, frame: Array, obs: Array, flag: Array,
               truth: Array | None, ref: int) -> None:
        if t < self.w0:
            return
        valid = ~np.isnan(gen)
        ages = t - gen[valid]
        self.ages.append(ages)
        spread = int(frame[valid].max() - frame[valid].min()) if ages.size else 0
        self.spread.append(spread)
        if truth is not None and ages.size:
            err = np.linalg.norm(obs[valid, 9:12] - truth[valid], axis=1)
            self.errs.append(err[~np.isnan(err)])
        self.counts[0] += int(valid.sum())
        self.counts[1] += int(np.count_nonzero(flag == FILLED))
        self.counts[2] += int(np.count_nonzero(flag == EXTRAPOLATED))
        if ref >= 0:
            self.counts[3] += int(np.count_nonzero(frame[valid] != ref))
        self.mean.append(float(ages.mean()) if ages.size else math.nan)
        self.max.append(float(ages.max()) if ages.size else math.nan)


def _finish(col: Collector, duration: float) -> dict[str, float]:
    link = SimpleNamespace(name="l", bytes=1, packets=1)
    net = SimpleNamespace(links=lambda: [link], retransmissions=0, gave_up=0, broker_work=0.0,
                          broker_max_wait=0.0)
    out = col.finish(RunReport(f_trig=100.0, rollbacks=0, resim_steps=0, history_misses=0,
                               wall_seconds=1.0, events=1),
                     AlignerReport(peak_bytes=0), NetReport.of(net))
    return out["metrics"]


def _bits(x: float) -> bytes:
    return np.float64(x).tobytes()


def _play(seed: int) -> tuple[Collector, _Reference, float]:
    """A random run of align ticks (``shown``) and render ticks on one collector and the
    reference: states that arrive, repeat, go back in time or stay unknown, NaN positions,
    every flag, ticks with and without truth and reference frame."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    w0, duration = float(rng.uniform(0.0, 0.5)), 1.0
    spec = CollectorSpec(nodes=n, warmup=w0, duration=duration, f_trig=100.0,
                         history_frames=16, stall_threshold=0.1)
    col, ref = Collector(spec, "bides"), _Reference(n, w0)
    gen = np.full(n, np.nan)
    frame = np.full(n, -1, dtype=np.int64)
    for tick in range(int(rng.integers(5, 60))):
        t = tick * duration / 60
        move = rng.random(n) < rng.uniform(0.0, 1.0)
        new = t - rng.exponential(0.05, n)
        gen = np.where(move, new, gen)   # some go back in time: not newer, ignored
        gen[rng.random(n) < 0.02] = np.nan
        frame = np.where(move, np.floor(new * 100).astype(np.int64), frame)
        col.shown(t, gen)
        ref.shown(t, gen)
        obs = rng.normal(0.0, 50.0, (n, 12))
        obs[rng.random(n) < 0.05, 9:12] = np.nan
        truth = None if rng.random() < 0.3 else obs[:, 9:12] + rng.normal(0.0, 2.0, (n, 3))
        flag = rng.integers(0, 4, n).astype(np.uint8)
        r = -1 if rng.random() < 0.3 else int(np.nanmax(frame, initial=0))
        col.render(t + 0.004, gen, frame, obs, flag, truth, 100.0, tick, r)
        ref.render(t + 0.004, gen, frame, obs, flag, truth, r)
    return col, ref, duration


@pytest.mark.parametrize("seed", range(10))
def test_collector_ticks_match_numpy_bit_for_bit(seed: int) -> None:
    col, ref, duration = _play(seed)
    ages = np.concatenate([np.empty(0), *ref.ages])
    assert col.aoi_samples().tobytes() == ages.tobytes()
    assert [_bits(x) for x in col.ts["aoi_mean"]] == [_bits(x) for x in ref.mean]
    assert [_bits(x) for x in col.ts["aoi_max"]] == [_bits(x) for x in ref.max]
    assert col.ts["spread"] == ref.spread
    m = _finish(col, duration)
    errs = np.concatenate([np.empty(0), *ref.errs])
    if errs.size:
        assert (_bits(m["pos_err_mean"]), _bits(m["pos_err_max"])) == (
            _bits(errs.mean()), _bits(errs.max()))
    shown = max(1, ref.counts[0])
    assert (m["filled_frac"], m["extrapolated_frac"], m["off_frame_frac"]) == (
        ref.counts[1] / shown, ref.counts[2] / shown, ref.counts[3] / shown)
    fin = col.aoi.finish(duration)
    # AoITracker.finish's arithmetic on the reference tracker's state
    assert fin["peak_count"] == ref.peak_count
    assert _bits(fin["peak_mean"]) == _bits(
        ref.peak_sum / ref.peak_count if ref.peak_count else math.nan)
    shown_nodes = ~np.isnan(ref.gen)
    a = ref.acc[shown_nodes]
    area = float(np.sum(ref.area[shown_nodes] + np.maximum(duration - a, 0.0)
                        * ((duration + a) * 0.5 - ref.gen[shown_nodes])))
    node_time = float(np.sum(np.maximum(duration - ref.start[shown_nodes], 0.0)))
    assert _bits(fin["time_average"]) == _bits(area / node_time if node_time > 0 else math.nan)
    assert fin["peak_count"] > 0 or seed > 0


def test_render_hand_computed() -> None:
    spec = CollectorSpec(nodes=3, warmup=0.0, duration=1.0, f_trig=100.0, history_frames=16,
                         stall_threshold=0.1)
    col = Collector(spec, "bides")
    obs = np.zeros((3, 12))
    obs[:, 9:12] = [[3.0, 4.0, 0.0], [9.0, 9.0, 9.0], [1.0, 2.0, 2.0]]
    truth = np.zeros((3, 3))
    truth[2] = [np.nan, 0.0, 0.0]  # node 2's error is NaN: left out
    flag = np.array([FILLED, EXTRAPOLATED, FILLED], dtype=np.uint8)
    # node 1 has no state: ages 0.5 - 0.25 and 0.5 - 0.375, frames 7 and 4 (spread 3)
    col.render(0.5, np.array([0.25, np.nan, 0.375]), np.array([7, 0, 4]), obs, flag,
               truth, 100.0, 9, 7)
    assert col.aoi_samples().tolist() == [0.25, 0.125]
    assert col.ts["aoi_mean"] == [0.1875] and col.ts["aoi_max"] == [0.25]
    assert col.ts["spread"] == [3]
    m = _finish(col, 1.0)
    assert m["pos_err_mean"] == 5.0 and m["pos_err_max"] == 5.0  # |(3, 4, 0)|
    assert (m["filled_frac"], m["extrapolated_frac"], m["off_frame_frac"]) == (1.0, 0.5, 0.5)


def test_render_with_no_state_and_wrong_shapes() -> None:
    spec = CollectorSpec(nodes=2, warmup=0.0, duration=1.0, f_trig=100.0, history_frames=16,
                         stall_threshold=0.1)
    col = Collector(spec, "none")
    col.render(0.1, np.full(2, np.nan), np.zeros(2, np.int64), np.zeros((2, 12)),
               np.zeros(2, np.uint8), None, 100.0, 0, -1)
    assert np.isnan(col.ts["aoi_mean"][0]) and col.ts["spread"] == [0]
    with pytest.raises(ValueError, match="render: rows of 2 nodes"):
        col.render(0.2, np.zeros(3), np.zeros(3, np.int64), np.zeros((3, 12)),
                   np.zeros(3, np.uint8), None, 100.0, 0, -1)
    with pytest.raises(ValueError, match="shown: 2 generation times"):
        col.shown(0.2, np.zeros(5))


def test_aoi_node_ids_as_numpy_indexes_them() -> None:
    tr = AoITracker(3, t_start=0.0)
    tr.update(1.0, np.array([-1, 0]), np.array([0.5, 0.25]))  # -1 is node 2
    now = tr.current(1.0)
    assert now[0] == 0.75 and np.isnan(now[1]) and now[2] == 0.5
    with pytest.raises(IndexError, match="node 3 is out of range for 3 nodes"):
        tr.update(2.0, np.array([0, 3]), np.array([1.5, 1.5]))
    assert tr.current(2.0)[0] == 1.75  # nothing changed


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e6])
def test_pairwise_sum_is_numpys(scale: float) -> None:
    rng = np.random.default_rng(int(scale * 1000) % 97)
    a = rng.lognormal(0.0, 2.0, 300_000) * scale * rng.choice([-1.0, 1.0], 300_000)
    sizes = [*range(0, 300), 383, 1024, 1031, 4096 + 13, 65_537, 299_990]
    for n in sizes:
        lo = int(rng.integers(0, a.size - n + 1))
        assert _bits(0.0 + pairwise_sum(a, lo, n)) == _bits(np.sum(a[lo:lo + n])), n
