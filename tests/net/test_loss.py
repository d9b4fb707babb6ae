"""Loss processes: exact draws, the Gilbert–Elliott chain against a sequential
reference, order independence, stationary rates and validation."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError
from sigma_des.net.loss import LossProcess, LossSpec

S = Stream(3, "loss")
LINK = 4


def _reference_chain(spec: LossSpec, stream: Stream, link: int, n: int) -> np.ndarray:
    """The GE chain, one slot at a time (the definition in loss.py's docstring)."""
    u = stream.uniform(link, -1, np.arange(n))
    bad = np.empty(n, dtype=bool)
    state = bool(u[0] < spec.bad_fraction)
    bad[0] = state
    for s in range(1, n):
        state = (not u[s] < spec.p_bg) if state else bool(u[s] < spec.p_gb)
        bad[s] = state
    return bad


GE = LossSpec(model="gilbert_elliott", p_gb=0.01, p_bg=0.1, loss_good=0.0, loss_bad=1.0)


def test_bernoulli_is_a_threshold_on_the_stream() -> None:
    proc = LossProcess(LossSpec(p=0.3), S, LINK)
    kind, node, frame = 1, np.arange(50)[:, None], np.arange(2000)
    lost = proc.lost(0.0, kind, node, frame)
    assert lost.shape == (50, 2000)
    np.testing.assert_array_equal(lost, S.uniform(LINK, kind, node, frame) < 0.3)
    # 1e5 Bernoulli(0.3): SE = 1.45e-3
    assert abs(lost.mean() - 0.3) < 7e-3
    assert proc.expected_loss() == 0.3


def test_bernoulli_zero_loses_nothing_and_broadcasts_with_t() -> None:
    proc = LossProcess(LossSpec(), S, LINK)
    lost = proc.lost(np.array([0.1, 0.2, 0.3]), 1, 2)
    assert lost.shape == (3,) and not lost.any()


def test_extra_p_uses_an_independent_draw() -> None:
    ids = (2, np.arange(100_000))
    base = LossProcess(LossSpec(p=0.2), S, LINK)
    only_extra = LossProcess(LossSpec(), S, LINK).lost(1.0, *ids, extra_p=0.5)
    np.testing.assert_array_equal(only_extra, S.uniform(LINK, -2, *ids) < 0.5)
    both = base.lost(1.0, *ids, extra_p=0.5)
    np.testing.assert_array_equal(both, base.lost(1.0, *ids) | only_extra)
    # independent: P(lost) = 1 - 0.8 * 0.5 = 0.6, SE 1.5e-3
    assert abs(both.mean() - 0.6) < 8e-3
    # per-packet extra_p
    per = LossProcess(LossSpec(), S, LINK).lost(1.0, 2, np.arange(4), extra_p=[0, 0, 1, 1])
    np.testing.assert_array_equal(per, [False, False, True, True])


def test_ge_chain_matches_sequential_reference_across_chunks() -> None:
    n = 400_000
    ref = _reference_chain(GE, S, LINK, n)
    proc = LossProcess(GE, S, LINK)
    # Ask out of order so the chain is built in several chunks (65536, then 150001, …).
    slots = np.array([10, 150_000, 3, 399_999, 70_000])
    got = proc.bad_state((slots + 0.5) * GE.slot)
    np.testing.assert_array_equal(got, ref[slots])
    np.testing.assert_array_equal(proc.bad_state((np.arange(n) + 0.5) * GE.slot), ref)


def test_ge_state_does_not_depend_on_query_order() -> None:
    t = np.linspace(0.0, 300.0, 801)
    a = LossProcess(GE, S, LINK)
    forward = np.concatenate([a.lost(ti, 0, i) for i, ti in enumerate(t)])
    b = LossProcess(GE, S, LINK)
    backward = np.concatenate([b.lost(ti, 0, i) for i, ti in reversed(list(enumerate(t)))])
    np.testing.assert_array_equal(forward, backward[::-1])
    np.testing.assert_array_equal(forward, LossProcess(GE, S, LINK).lost(t, 0, np.arange(t.size)))


def test_ge_loss_is_state_dependent_threshold() -> None:
    spec = LossSpec(model="gilbert_elliott", p_gb=0.05, p_bg=0.2, loss_good=0.1, loss_bad=0.7)
    proc = LossProcess(spec, S, LINK)
    t = np.arange(20_000) * 0.0007
    ids = (1, np.arange(20_000))
    p = np.where(proc.bad_state(t), 0.7, 0.1)
    np.testing.assert_array_equal(proc.lost(t, *ids), S.uniform(LINK, *ids) < p)


def test_ge_stationary_rate_and_burst_length() -> None:
    proc = LossProcess(GE, S, LINK)
    bad = proc.bad_state((np.arange(400_000) + 0.5) * GE.slot)
    assert GE.bad_fraction == pytest.approx(1 / 11)
    assert proc.expected_loss() == pytest.approx(1 / 11)
    # ~3600 bad bursts: the bad fraction's SE is ~0.006 relative; allow 10 %
    assert bad.mean() == pytest.approx(1 / 11, rel=0.1)
    edges = np.flatnonzero(np.diff(bad.astype(np.int8)))
    runs = np.diff(edges)[(0 if bad[edges[0] + 1] else 1) :: 2]  # bad runs
    assert runs.mean() == pytest.approx(1 / GE.p_bg, abs=1.0)  # geometric, mean 10


def test_ge_swap_and_absorbing_chains() -> None:
    # p_gb = p_bg = 1: the state flips every slot.
    flip = LossSpec(model="gilbert_elliott", p_gb=1.0, p_bg=1.0, loss_bad=1.0)
    bad = LossProcess(flip, S, LINK).bad_state((np.arange(1000) + 0.5) * flip.slot)
    assert np.all(bad[1:] != bad[:-1])
    # p_bg = 0: once bad, bad forever (here from slot 1 on, as p_gb = 1).
    sink = LossSpec(model="gilbert_elliott", p_gb=1.0, p_bg=0.0, loss_bad=0.5)
    assert sink.expected_loss() == 0.5
    bad = LossProcess(sink, S, LINK).bad_state((np.arange(1000) + 0.5) * sink.slot)
    assert bad.all()


def test_negative_time_rejected() -> None:
    with pytest.raises(ValueError):
        LossProcess(GE, S, LINK).lost(-1.0, 0)


def test_validation() -> None:
    with pytest.raises(ConfigError) as e:
        LossSpec(p=1.0)
    assert e.value.key == "p" and "every packet" in e.value.reason
    with pytest.raises(ConfigError) as e:
        LossSpec(p=-0.1)
    assert e.value.key == "p" and "[0, 1)" in e.value.reason
    for field in ("p_gb", "p_bg", "loss_good", "loss_bad"):
        with pytest.raises(ConfigError) as e:
            LossSpec(**{field: 1.5})
        assert e.value.key == field and "[0, 1]" in e.value.reason
    with pytest.raises(ConfigError) as e:
        LossSpec(slot=0)
    assert e.value.key == "slot"
    with pytest.raises(ConfigError) as e:
        LossSpec(model="markov")
    assert e.value.key == "model" and "gilbert_elliott" in e.value.reason
    with pytest.raises(ConfigError) as e:
        LossSpec(model="gilbert_elliott", loss_good=1.0)
    assert e.value.key == "loss_good" and "every packet" in e.value.reason
    with pytest.raises(ConfigError) as e:
        LossSpec(model="gilbert_elliott", p_gb=0.1, p_bg=0.0, loss_bad=1.0)
    assert e.value.key == "loss_bad"
    spec = LossSpec(model="gilbert_elliott", p_bg=1, slot=1)
    assert isinstance(spec.p_bg, float) and isinstance(spec.slot, float)
