"""Live payload codec: exact sizes, round trips, and every kind of bad payload rejected."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from sigma_des.live.wire import (
    REREQUEST_BYTES,
    STATE_BYTES,
    TRIGGER_BYTES,
    Topics,
    WireError,
    command_bytes,
    decode_command,
    decode_rerequest,
    decode_state,
    decode_trigger,
    encode_command,
    encode_rerequest,
    encode_state,
    encode_trigger,
    run_token,
    state_topic_bytes,
)
from sigma_des.net.kinds import STATE


def test_sizes_are_the_documented_ones() -> None:
    assert TRIGGER_BYTES == 33
    assert STATE_BYTES == 93
    assert len(encode_command(1, 2, 3, 0.5, np.zeros(4))) == command_bytes(4) == 23 + 8 * 4
    assert len(encode_rerequest(1, 2, 3, 0.5)) == REREQUEST_BYTES == 21


def test_a_state_topic_has_the_same_length_in_every_run_of_a_method() -> None:
    tokens = {run_token("bides") for _ in range(3)}
    assert len(tokens) == 3 and all(len(t) == 8 + 5 for t in tokens)
    for t in tokens:
        assert len(Topics(t).state(12)) == state_topic_bytes("bides", 12)
    assert state_topic_bytes("bides", 12) == len("sd/") + 13 + len("/up/h12/state") == 29


def test_round_trips() -> None:
    assert decode_trigger(encode_trigger(7, 0.07, 0.01, -math.inf, 0)) == (
        7, 0.07, 0.01, -math.inf, 0)
    obs = np.arange(12, dtype=np.float64) * 0.5  # exactly representable in float32
    # a republish of frame 9's state answering re-request 2 of frame 10: 10 * 64 + 2
    kind, node, frame, index, tg, ts, hl, hc, back = decode_state(
        encode_state(3, 9, 0.25, 0.5, 0.125, 4, obs, republish=True, index=642), n=4)
    assert (kind, node, frame, index, tg, ts, hl, hc) == (5, 3, 9, 642, 0.25, 0.5, 0.125, 4)
    np.testing.assert_array_equal(back, obs)
    assert decode_state(encode_state(3, 9, 0.25, 0.5, 0.125, 4, obs), n=4)[:4] == (
        STATE, 3, 9, 9)  # a state's index is its frame
    with pytest.raises(ValueError, match="re-request"):
        encode_state(3, 9, 0.25, 0.5, 0.125, 4, obs, republish=True)
    vals = np.array([1.5, math.nan, -2.0])
    node, stamp, tick, ts, v = decode_command(encode_command(2, -1, 11, 0.3, vals), width=3)
    assert (node, stamp, tick, ts) == (2, -1, 11, 0.3)
    np.testing.assert_array_equal(v, vals)  # NaN ('keep') survives
    assert decode_rerequest(encode_rerequest(5, 6, 2, 1.0)) == (5, 6, 2, 1.0)


@pytest.mark.parametrize(
    "payload",
    [
        b"",
        encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))[:-1],  # truncated
        encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12)) + b"x",  # oversized
        encode_state(0, 1, math.nan, 0.0, 0.0, 0, np.zeros(12)),  # NaN time
        encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.full(12, math.nan)),  # NaN state
        encode_state(0, 1, 0.0, math.inf, 0.0, 0, np.zeros(12)),  # infinite time
        encode_state(9, 1, 0.0, 0.0, 0.0, 0, np.zeros(12)),  # node out of range
        # a republish of frame 9 answering a re-request of frame 8 (it cannot be older)
        encode_state(0, 9, 0.0, 0.0, 0.0, 0, np.zeros(12), republish=True, index=8 * 64 + 3),
        # a state whose index is not its frame
        encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))[:9] + (2).to_bytes(8, "little")
        + encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))[17:],
        b"\x07" + encode_state(0, 1, 0.0, 0.0, 0.0, 0, np.zeros(12))[1:],  # wrong kind
        encode_trigger(1, 0.0, 0.01, 0.0, 0),  # a trigger is not a state
    ],
)
def test_bad_states_raise(payload: bytes) -> None:
    with pytest.raises(WireError):
        decode_state(payload, n=4)


def test_bad_triggers_and_commands_raise() -> None:
    with pytest.raises(WireError):
        decode_trigger(encode_trigger(1, 0.0, 0.0, 0.0, 0))  # dt = 0
    with pytest.raises(WireError):
        decode_trigger(encode_trigger(1, math.nan, 0.01, 0.0, 0))
    with pytest.raises(WireError):
        decode_command(encode_command(1, 0, 0, 0.0, np.zeros(3)), width=4)  # wrong width
    with pytest.raises(WireError):
        decode_command(encode_command(1, 0, 0, 0.0, np.array([math.inf])), width=1)
    with pytest.raises(WireError):
        decode_command(struct.pack("<BI", 3, 1), width=1)  # shorter than the header
    with pytest.raises(WireError):
        decode_rerequest(b"\x04" * 20)


def test_topics_parse_only_ours() -> None:
    tp = Topics("abc")
    assert tp.parse_up(tp.state(3)) == (3, "state")
    assert tp.parse_up(tp.ready(0)) == (0, "ready")
    assert tp.parse_up("sd/abc/up/h1/garbage") is None
    assert tp.parse_up("sd/other/up/h1/state") is None
    assert tp.parse_up("sd/abc/up/hx/state") is None
    assert tp.parse_up(tp.trig) is None


def test_ned_rotates_body_velocity_and_flips_altitude() -> None:
    from sigma_des.live.messages import ned

    obs = np.zeros((2, 12))
    obs[:, 0] = 1.0  # u = 1 m/s forward
    obs[:, 9:12] = [10.0, 20.0, 30.0]  # x north, y east, h up
    obs[1, 5] = math.pi / 2  # heading east
    pos, vel, att = ned(obs)
    np.testing.assert_allclose(pos, [[10.0, 20.0, -30.0]] * 2)
    np.testing.assert_allclose(vel, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(att[1], [0.0, 0.0, math.pi / 2])
