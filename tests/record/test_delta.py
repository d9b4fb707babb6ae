"""Incremental storage: dead-band, keyframes and bit-exact decoding."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sigma_des.record import Recorder, read_states
from sigma_des.record.delta import DeltaEncoder, decode


def _enc(**kw: float) -> DeltaEncoder:
    p = {"deadband_pos": 0.05, "deadband_vel": 0.1, "deadband_att": 0.02, "keyframe_every": 10}
    p.update(kw)
    return DeltaEncoder(p["deadband_pos"], p["deadband_vel"], p["deadband_att"],
                        int(p["keyframe_every"]))


def test_constant_velocity_stores_only_keyframes() -> None:
    """Dead reckoning predicts uniform motion exactly: frames 0, 10, 20 are stored."""
    e = _enc()
    stored = []
    for k in range(25):
        t = 0.01 * k
        vals = np.array([[2.0 * t, 0.0, -5.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.3]])
        rows, key, _v = e.encode(np.array([0]), np.array([k]), np.array([t]), vals)
        if rows.size:
            stored.append((k, int(key[0])))
    assert stored == [(0, 1), (10, 1), (20, 1)]
    assert e.seen == 25 and e.written == 3


def test_a_step_beyond_the_dead_band_is_stored_as_a_delta() -> None:
    e = _enc(keyframe_every=100)
    base = np.zeros((1, 9))
    e.encode(np.array([0]), np.array([0]), np.array([0.0]), base)
    small = base.copy()
    small[0, 0] = 0.04  # inside the 0.05 m dead-band
    assert e.encode(np.array([0]), np.array([1]), np.array([0.01]), small)[0].size == 0
    big = base.copy()
    big[0, 0] = 0.0612345678
    rows, key, v = e.encode(np.array([0]), np.array([2]), np.array([0.02]), big)
    assert rows.tolist() == [0] and key.tolist() == [0]
    assert v[0, 0] == 0.061235  # rounded to 6 decimals
    turn = base.copy()
    turn[0, 0] = 0.061235
    turn[0, 8] = 0.03  # yaw changed by more than 0.02 rad
    assert e.encode(np.array([0]), np.array([3]), np.array([0.02]), turn)[0].size == 1


def test_decode_repeats_the_encoders_running_values_bitwise() -> None:
    rng = np.random.default_rng(7)  # local generator: test data only
    e = _enc(keyframe_every=7)
    nodes_all, key_all, val_all = [], [], []
    for k in range(60):
        nd = np.array([0, 1, 2, 1])  # node 1 twice in a batch
        vals = np.cumsum(rng.normal(0, 0.2, (4, 9)), axis=0) + k
        rows, key, v = e.encode(nd, np.array([k, k, k, k]), np.full(4, 0.01 * k), vals)
        nodes_all.append(nd[rows])
        key_all.append(key)
        val_all.append(v)
    nodes = np.concatenate(nodes_all)
    out = decode(nodes, np.concatenate(key_all), np.concatenate(val_all))
    for i in range(3):
        last = out[nodes == i][-1]
        assert np.array_equal(last, e.last[i])  # bit-identical, not approximately


def test_decode_refuses_a_stream_without_a_first_keyframe() -> None:
    with pytest.raises(ValueError, match="node 4"):
        decode(np.array([4]), np.array([0], dtype=np.int8), np.zeros((1, 9)))


def test_incremental_recording_round_trip_error_within_dead_band(tmp_path: Path) -> None:
    """Stored states decode to within rounding of the originals; far fewer are stored."""
    path = tmp_path / "i.mcap"
    t = np.arange(300) * 0.01
    pos = np.stack([np.sin(t), 5 * t, -20 + 0 * t], axis=1)  # acceleration <= 1 m/s^2
    vel = np.stack([np.cos(t), 5 + 0 * t, 0 * t], axis=1)
    att = np.zeros((300, 3))
    with Recorder(path, mode="incremental", deadband_pos=0.05, keyframe_every=50) as rec:
        r = rec.run("none")
        for k in range(300):
            r.state(node=0, frame=k, t_send=t[k], t_recv=t[k] + 0.002,
                    pos=pos[k], vel=vel[k], att=att[k])
    st = read_states(path)["none"]
    assert 6 <= st.node.size < 60  # velocity drifts 0.1 m/s in >= 10 frames
    np.testing.assert_allclose(st.pos, pos[st.frame], atol=1e-5)
    np.testing.assert_allclose(st.vel, vel[st.frame], atol=1e-5)
    assert (st.frame[np.r_[0]] == 0).all() and set(range(0, 300, 50)) <= set(st.frame.tolist())
