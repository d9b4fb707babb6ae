"""BiDES swarm state alignment (Algorithm 1): hand-computed snapshots, a naive
per-node reference on random buffers, ring-buffer semantics and speed."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.flags import EXACT, EXTRAPOLATED, FILLED, MISSING
from sigma_des.events.align.ring import AlignResult, RingBuffers, align, insert_row


def _fill(buf: RingBuffers, node: int, frames: list[int], value=lambda f: float(f)) -> None:
    for f in frames:
        assert buf.insert(node, f, 0.01 * f + node, np.full(buf.width, value(f)))


def test_all_exact_at_min_latest() -> None:
    buf = RingBuffers(3, 5, 2)
    _fill(buf, 0, [0, 1, 2, 3])
    _fill(buf, 1, [0, 1, 2])
    _fill(buf, 2, [0, 1, 2, 3, 4])
    r = align(buf, theta_lag=None, hole_fill=True)
    assert r.aligned_frame == 2
    np.testing.assert_array_equal(r.frame, [2, 2, 2])
    np.testing.assert_array_equal(r.flag, [EXACT] * 3)
    np.testing.assert_array_equal(r.gen_time, [0.02, 1.02, 2.02])
    np.testing.assert_array_equal(r.obs, np.full((3, 2), 2.0))
    assert r.flag.dtype == np.uint8 and r.frame.dtype == np.int64


def test_hole_interpolated_or_held() -> None:
    buf = RingBuffers(2, 5, 1)
    _fill(buf, 0, [0, 4], value=lambda f: 2.0 * f)  # frames 1–3 lost; obs 0 and 8
    _fill(buf, 1, [0, 1])
    r = align(buf, theta_lag=None, hole_fill=True)
    assert r.aligned_frame == 1
    # w = (1 - 0) / (4 - 0) = 0.25 -> 0 + 0.25 * 8 = 2
    assert r.obs[0, 0] == 2.0 and r.flag[0] == FILLED
    assert r.frame[0] == 1 and r.gen_time[0] == 0.0  # frame F, gen time of the lower state
    assert r.flag[1] == EXACT
    held = align(buf, theta_lag=None, hole_fill=False)
    assert held.obs[0, 0] == 0.0 and held.frame[0] == 0 and held.flag[0] == FILLED
    assert held.gen_time[0] == 0.0


def test_hole_with_only_newer_neighbour() -> None:
    buf = RingBuffers(2, 4, 1)
    _fill(buf, 0, [3, 4])  # its first frames were lost
    _fill(buf, 1, [0, 1, 2])
    r = align(buf, theta_lag=None, hole_fill=True)
    assert r.aligned_frame == 2
    assert (r.frame[0], r.flag[0], r.obs[0, 0], r.gen_time[0]) == (3, FILLED, 3.0, 0.03)
    r = align(buf, theta_lag=None, hole_fill=False)
    assert r.flag[0] == MISSING and r.frame[0] == -1
    assert np.isnan(r.gen_time[0]) and np.isnan(r.obs[0]).all()


def test_lag_exclusion_and_extrapolation() -> None:
    buf = RingBuffers(3, 4, 2)
    _fill(buf, 0, list(range(11)))
    _fill(buf, 1, list(range(10)))
    _fill(buf, 2, [4, 5], value=lambda f: 0.5 * f - 1.0)  # obs 1.0 at 4, 1.5 at 5
    r = align(buf, theta_lag=2, hole_fill=True)
    assert r.aligned_frame == 9
    np.testing.assert_array_equal(r.flag, [EXACT, EXACT, EXTRAPOLATED])
    # 1.5 + (1.5 - 1.0) * (9 - 5) / (5 - 4) = 3.5
    np.testing.assert_array_equal(r.obs[2], [3.5, 3.5])
    assert r.frame[2] == 9 and r.gen_time[2] == 2.05  # shown at F (issue 9.3)
    # theta_lag large enough (5) or None: node 2 holds everyone back
    for theta in (5, None):
        r = align(buf, theta_lag=theta, hole_fill=True)
        assert r.aligned_frame == 5
        # node 0 (k=4) holds 7..10 only: frame 5 is gone; nearest above is 7
        assert (r.flag[0], r.frame[0]) == (FILLED, 7)
        assert (r.flag[2], r.frame[2]) == (EXACT, 5)


def test_excluded_node_with_single_state_is_copied() -> None:
    buf = RingBuffers(2, 4, 1)
    _fill(buf, 0, [20])
    _fill(buf, 1, [3])
    r = align(buf, theta_lag=4, hole_fill=False)
    assert r.aligned_frame == 20
    assert (r.flag[1], r.frame[1], r.obs[1, 0]) == (EXTRAPOLATED, 20, 3.0)


def test_aligned_frame_never_decreases() -> None:
    buf = RingBuffers(2, 8, 1)
    _fill(buf, 0, [0, 1, 2, 3, 4, 5, 6])
    _fill(buf, 1, [0, 1, 2, 3, 4, 5, 6])
    first = align(buf, theta_lag=None, hole_fill=True)
    assert first.aligned_frame == 6
    late = RingBuffers(3, 8, 1)  # a node joins late with old frames
    _fill(late, 0, [6, 7])
    _fill(late, 1, [6, 7])
    _fill(late, 2, [3, 4])
    r = align(late, theta_lag=None, hole_fill=True, prev_frame=first.aligned_frame)
    assert r.aligned_frame == 6
    np.testing.assert_array_equal(r.flag, [EXACT, EXACT, FILLED])
    assert r.frame[2] == 4 and r.obs[2, 0] == 4.0  # only the older neighbour: copied


def test_no_state_at_all() -> None:
    r = align(RingBuffers(3, 4, 2), theta_lag=1, hole_fill=True, prev_frame=7)
    assert r.aligned_frame == 7
    np.testing.assert_array_equal(r.flag, [MISSING] * 3)
    np.testing.assert_array_equal(r.frame, [-1] * 3)
    assert np.isnan(r.obs).all() and r.obs.shape == (3, 2)


def test_node_without_state_is_missing_and_not_considered() -> None:
    buf = RingBuffers(3, 4, 1)
    _fill(buf, 0, [1, 2])
    _fill(buf, 2, [2, 3])
    r = align(buf, theta_lag=None, hole_fill=True)
    assert r.aligned_frame == 2
    np.testing.assert_array_equal(r.flag, [EXACT, MISSING, EXACT])


def test_ring_wraparound_and_duplicates() -> None:
    buf = RingBuffers(1, 4, 1)
    _fill(buf, 0, list(range(10)))
    np.testing.assert_array_equal(buf.frame[0], [8, 9, 6, 7])
    assert buf.latest[0] == 9
    assert not buf.insert(0, 9, 99.0, np.array([99.0]))  # duplicate
    assert buf.gen_time[0, 1] == 0.09
    assert not buf.insert(0, 5, 99.0, np.array([99.0]))  # slot 1 holds newer 9
    buf2 = RingBuffers(1, 4, 1)
    _fill(buf2, 0, [7])
    assert buf2.insert(0, 6, 0.5, np.array([6.0]))  # older, but its slot (2) is free
    assert not buf2.insert(0, 3, 0.5, np.array([3.0]))  # slot 3 holds the newer 7
    assert buf2.latest[0] == 7
    with pytest.raises(ValueError):
        buf2.insert(0, -1, 0.0, np.array([0.0]))


def test_nbytes() -> None:
    # frame 3*4*8 + gen_time 3*4*8 + obs 3*4*2*8 + latest 3*8
    assert RingBuffers(3, 4, 2).nbytes == 96 + 96 + 192 + 24


def test_batch_insert_equals_sequential_inserts() -> None:
    rng = np.random.default_rng(1)
    n, k, w, m = 20, 6, 3, 3000
    nodes = rng.integers(0, n, m)
    frames = rng.integers(0, 40, m)
    gens = rng.random(m)
    obs = rng.random((m, w))
    seq = RingBuffers(n, k, w)
    for i in range(m):
        seq.insert(int(nodes[i]), int(frames[i]), float(gens[i]), obs[i])
    bat = RingBuffers(n, k, w)
    for lo in range(0, m, 500):  # several batches, with duplicates inside each
        sl = slice(lo, lo + 500)
        bat.insert(nodes[sl], frames[sl], gens[sl], obs[sl])
    np.testing.assert_array_equal(bat.frame, seq.frame)
    np.testing.assert_array_equal(bat.gen_time, seq.gen_time)
    np.testing.assert_array_equal(bat.obs, seq.obs)
    np.testing.assert_array_equal(bat.latest, seq.latest)


def _reference(buf: RingBuffers, theta_lag: int | None, hole_fill: bool, prev: int) -> AlignResult:
    """Per-node loop following the rules in ring.py's docstring."""
    n, w = buf.n, buf.width
    res = AlignResult(
        prev, np.full(n, -1), np.full(n, np.nan), np.full((n, w), np.nan), np.full(n, MISSING)
    )
    states = [
        {int(f): (buf.gen_time[i, s], buf.obs[i, s]) for s, f in enumerate(buf.frame[i]) if f >= 0}
        for i in range(n)
    ]
    lat = [max(st) if st else -1 for st in states]
    have = [i for i in range(n) if lat[i] >= 0]
    if not have:
        return res
    top = max(lat[i] for i in have)
    cons = [i for i in have if theta_lag is None or top - lat[i] <= theta_lag]
    F = max(prev, min(lat[i] for i in cons))  # noqa: N806
    res.aligned_frame = F
    for i in have:
        st = states[i]
        if i not in cons:
            f1 = max(st)
            older = [f for f in st if f < f1]
            g1, o1 = st[f1]
            if older:
                f0 = max(older)
                o = o1 + (o1 - st[f0][1]) * (F - f1) / (f1 - f0)
            else:
                o = o1
            res.frame[i], res.gen_time[i], res.obs[i], res.flag[i] = F, g1, o, EXTRAPOLATED
            continue
        if F in st:
            res.frame[i], (res.gen_time[i], res.obs[i]), res.flag[i] = F, st[F], EXACT
            continue
        lo = max([f for f in st if f < F], default=None)
        hi = min([f for f in st if f > F], default=None)
        if hole_fill and lo is not None and hi is not None:
            (g0, o0), (_, o1) = st[lo], st[hi]
            o = o0 + (F - lo) / (hi - lo) * (o1 - o0)
            res.frame[i], res.gen_time[i], res.obs[i], res.flag[i] = F, g0, o, FILLED
            continue
        src = lo if lo is not None else (hi if hole_fill else None)
        if src is not None:
            res.frame[i], (res.gen_time[i], res.obs[i]), res.flag[i] = src, st[src], FILLED
    return res


@pytest.mark.parametrize("theta_lag", [None, 0, 3])
@pytest.mark.parametrize("hole_fill", [True, False])
@pytest.mark.parametrize("prev", [-1, 12])
def test_matches_per_node_reference(theta_lag: int | None, hole_fill: bool, prev: int) -> None:
    rng = np.random.default_rng(5)
    n, k, w = 40, 6, 2
    buf = RingBuffers(n, k, w)
    for i in range(n):
        if i % 13 == 0:
            continue  # never sends
        top = int(rng.integers(5, 25))
        for f in range(top + 1):
            if rng.random() < 0.7:
                buf.insert(i, f, f * 0.01 + rng.random() * 1e-3, rng.normal(size=w))
    got = align(buf, theta_lag=theta_lag, hole_fill=hole_fill, prev_frame=prev)
    ref = _reference(buf, theta_lag, hole_fill, prev)
    assert got.aligned_frame == ref.aligned_frame
    np.testing.assert_array_equal(got.flag, ref.flag)
    np.testing.assert_array_equal(got.frame, ref.frame)
    np.testing.assert_array_equal(got.gen_time, ref.gen_time)
    np.testing.assert_allclose(got.obs, ref.obs, rtol=1e-12, atol=1e-12)
    assert len(set(got.flag.tolist())) >= 2


@pytest.mark.parametrize("seed", range(6))
def test_compiled_align_equals_the_numpy_one_bitwise(seed: int) -> None:
    """n = 1000, k = 30 with losses, stragglers and ring wrap-around: every output
    equal to the last bit to the former numpy implementation."""
    rng = np.random.default_rng(seed)
    n, k, w = 1000, 30, 12
    buf = RingBuffers(n, k, w)
    top = rng.integers(20, 80, size=n)
    top[rng.random(n) < 0.05] = 3  # stragglers
    for f in range(int(top.max()) + 1):
        ok = (rng.random(n) > 0.2) & (top >= f)
        nodes = np.flatnonzero(ok)
        buf.insert(nodes, np.full(nodes.size, f), f * 0.01 + rng.random(nodes.size),
                        rng.normal(size=(nodes.size, w)))
    for theta_lag, hole_fill, prev in ((5, True, -1), (None, True, 30), (3, False, 10),
                                       (0, False, -1)):
        got = align(buf, theta_lag=theta_lag, hole_fill=hole_fill, prev_frame=prev)
        ref = _numpy_align(buf, theta_lag, hole_fill, prev)
        assert got.aligned_frame == ref.aligned_frame
        for name in ("frame", "gen_time", "obs", "flag"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)


def _numpy_align(buf: RingBuffers, theta_lag: int | None, hole_fill: bool,
                 prev_frame: int) -> AlignResult:
    """The previous, numpy-vectorised implementation of ``align`` (kept as a bitwise
    reference for the compiled one)."""
    latest = buf.latest
    has = latest >= 0
    considered = has
    if theta_lag is not None:
        considered = has & (latest.max() - latest <= theta_lag)
    F = max(int(prev_frame), int(latest[considered].min()))  # noqa: N806
    n = buf.n
    rows = np.arange(n)
    fr = buf.frame
    valid = fr >= 0

    # Exact state at F.
    is_f = fr == F
    exact = considered & is_f.any(axis=1)
    s_exact = is_f.argmax(axis=1)

    # Nearest buffered frames below and above F.
    below = np.where(valid & (fr < F), fr, -1)
    s_lo = below.argmax(axis=1)
    f_lo = below[rows, s_lo]
    above = np.where(fr > F, fr, np.iinfo(np.int64).max)
    s_hi = above.argmin(axis=1)
    f_hi = above[rows, s_hi]
    has_lo = f_lo >= 0
    has_hi = f_hi != np.iinfo(np.int64).max

    hole = considered & ~exact
    if hole_fill:
        both = hole & has_lo & has_hi
        only = hole & (has_lo ^ has_hi)
        s_only = np.where(has_lo, s_lo, s_hi)
        filled = both | only
    else:
        both = np.zeros(n, dtype=np.bool_)
        only = hole & has_lo
        s_only = s_lo
        filled = only

    # Excluded (lagging) nodes: their two newest frames.
    excl = has & ~considered
    s_new = fr.argmax(axis=1)
    f_new = fr[rows, s_new]
    prev = fr.copy()
    prev[rows, s_new] = -1
    s_old = prev.argmax(axis=1)
    f_old = prev[rows, s_old]

    frame = np.full(n, -1, dtype=np.int64)
    gen = np.full(n, np.nan)
    obs = np.full((n, buf.width), np.nan)
    flag = np.full(n, MISSING, dtype=np.uint8)

    # Exact and single-source states are shown as stored.
    sel = np.where(exact, s_exact, s_only)
    shown = exact | only
    idx = rows[shown]
    frame[idx] = fr[idx, sel[idx]]
    gen[idx] = buf.gen_time[idx, sel[idx]]
    obs[idx] = buf.obs[idx, sel[idx]]
    flag[rows[exact]] = EXACT
    flag[rows[filled]] = FILLED

    # Interpolation across a hole.
    idx = rows[both]
    if idx.size:
        lo, hi = f_lo[idx], f_hi[idx]
        w = ((F - lo) / (hi - lo))[:, None]
        o_lo = buf.obs[idx, s_lo[idx]]
        o_hi = buf.obs[idx, s_hi[idx]]
        obs[idx] = o_lo + w * (o_hi - o_lo)
        gen[idx] = buf.gen_time[idx, s_lo[idx]]
        frame[idx] = F

    # Extrapolation of excluded nodes.
    idx = rows[excl]
    if idx.size:
        o_new = buf.obs[idx, s_new[idx]]
        two = f_old[idx] >= 0
        f1 = f_new[idx]
        f0 = np.where(two, f_old[idx], f1 - 1)
        o_old = np.where(two[:, None], buf.obs[idx, s_old[idx]], o_new)
        w = ((F - f1) / (f1 - f0))[:, None]
        obs[idx] = o_new + w * (o_new - o_old)
        gen[idx] = buf.gen_time[idx, s_new[idx]]
        frame[idx] = F
        flag[idx] = EXTRAPOLATED

    return AlignResult(aligned_frame=F, frame=frame, gen_time=gen, obs=obs, flag=flag)


def test_insert_row_is_the_insert_rule_for_one_row() -> None:
    """The rule the compiled core applies to each delivered state: a ring of 3 slots,
    observations taken from the first ``width`` columns of a wider source row."""
    buf = RingBuffers(2, 3, 2)
    src = np.array([[9.0, 9.0, 9.0], [1.0, 2.0, 7.0], [3.0, 4.0, 7.0]])

    def put(node: int, f: int, gen: float, r: int) -> bool:
        return bool(insert_row(buf.frame, buf.gen_time, buf.obs, buf.latest, node, f, gen,
                               src, r))

    assert put(0, 4, 0.04, 1)  # slot 1
    assert not put(0, 4, 0.05, 2)  # the same frame again: the first stays
    assert not put(0, 1, 0.01, 2)  # slot 1 holds a newer frame
    assert put(0, 7, 0.07, 2)  # slot 1 again, newer
    assert put(0, 5, 0.05, 1)  # slot 2, older than the newest: latest stays 7
    assert buf.frame.tolist() == [[-1, 7, 5], [-1, -1, -1]]
    assert buf.latest.tolist() == [7, -1]
    assert buf.gen_time[0, 1:].tolist() == [0.07, 0.05] and np.isnan(buf.gen_time[1]).all()
    assert buf.obs[0].tolist() == [[0.0, 0.0], [3.0, 4.0], [1.0, 2.0]]
    # insert() of the same rows in order gives the same buffers and says which were stored
    ref = RingBuffers(2, 3, 2)
    got = ref.insert([0, 0, 0, 0, 0], [4, 4, 1, 7, 5], [0.04, 0.05, 0.01, 0.07, 0.05],
                     src[[1, 2, 2, 2, 1], :2])
    assert got.tolist() == [True, False, False, True, True]
    for a, b in ((ref.frame, buf.frame), (ref.obs, buf.obs), (ref.latest, buf.latest)):
        np.testing.assert_array_equal(a, b)


def test_align_boxes_no_fresh_array_in_its_compiled_call() -> None:
    """Algorithm 1's compiled call writes into arrays allocated by the caller: numba
    boxes a fresh array through Python code (``_numba_unpickle``), where a Ctrl-C at an
    alignment tick would come out as a SystemError (test_record_durability)."""
    import numba.core.serialize as ser

    from sigma_des.events.align import ring as ring_mod

    buf = ring_mod.RingBuffers(3, 4, 2)
    for node, frame in ((0, 5), (1, 6), (2, 9)):
        buf.insert(node, frame, 0.01 * frame, np.full(2, float(frame)))
    ring_mod.align(buf, theta_lag=None, hole_fill=True, prev_frame=0)  # compiled now
    calls = []
    orig = ser._numba_unpickle
    ser._numba_unpickle = lambda *a: calls.append(a) or orig(*a)
    try:
        res = ring_mod.align(buf, theta_lag=None, hole_fill=True, prev_frame=0)
    finally:
        ser._numba_unpickle = orig
    assert calls == []
    assert res.aligned_frame == 5


def test_every_snapshot_owns_fresh_rows() -> None:
    """The rows start from shared blanks, copied: writing into one snapshot (the aligners
    keep and patch theirs) changes neither a later one nor an earlier one."""
    buf = RingBuffers(3, 4, 12)
    first = align(buf, theta_lag=None, hole_fill=True)  # no state yet: all blank
    first.frame[:] = 7
    first.gen_time[:] = 1.5
    first.obs[:] = 2.5
    first.flag[:] = EXACT
    buf.insert(np.array([0]), np.array([0]), np.array([0.01]), np.ones((1, 12)))
    second = align(buf, theta_lag=None, hole_fill=True)
    assert second.frame.tolist() == [0, -1, -1] and second.flag[1] == MISSING
    assert np.isnan(second.gen_time[1:]).all() and np.isnan(second.obs[1:]).all()
    third = align(RingBuffers(3, 4, 12), theta_lag=None, hole_fill=True)
    assert (third.frame == -1).all() and np.isnan(third.obs).all()
    assert (third.flag == MISSING).all() and first.frame.tolist() == [7, 7, 7]
    assert not np.shares_memory(second.obs, third.obs)
