"""MQTT 3.1.1 wire sizes against hand-computed packet layouts."""

from __future__ import annotations

import pytest

from sigma_des.net.wire import (
    PUBACK_BYTES,
    frame_bytes,
    payload_bytes,
    publish_bytes,
    remaining_length_bytes,
)


@pytest.mark.parametrize(
    ("n", "size"),
    [
        (0, 1),
        (127, 1),
        (128, 2),
        (16_383, 2),
        (16_384, 3),
        (2_097_151, 3),
        (2_097_152, 4),
        (268_435_455, 4),
    ],
)
def test_remaining_length_varint_boundaries(n: int, size: int) -> None:
    assert remaining_length_bytes(n) == size


@pytest.mark.parametrize("n", [-1, 268_435_456])
def test_remaining_length_out_of_range(n: int) -> None:
    with pytest.raises(ValueError):
        remaining_length_bytes(n)


def test_payload_bytes_rounds_up() -> None:
    assert payload_bytes(150) == 19  # the paper's 150-bit state
    assert payload_bytes(0) == 0
    assert payload_bytes(8) == 1
    assert payload_bytes(9) == 2


def test_state_publish_qos1() -> None:
    # 0x32 | rl=28 | topic len 2 | "s/123" 5 | packet id 2 | payload 19  -> 1+1+28 = 30
    assert publish_bytes("s/123", payload_bytes(150), 1) == 30
    assert publish_bytes(5, 19, 1) == 30  # topic given by its length


def test_state_publish_qos0_has_no_packet_id() -> None:
    assert publish_bytes("s/123", 19, 0) == 28


def test_two_byte_varint() -> None:
    # remaining = 2 + 5 + 200 = 207 >= 128 -> 2-byte varint: 1 + 2 + 207
    assert publish_bytes("s/123", 200, 0) == 210
    # QoS 1: remaining 209 -> 1 + 2 + 209
    assert publish_bytes("s/123", 200, 1) == 212


def test_varint_switch_at_128() -> None:
    assert publish_bytes(5, 120, 0) == 1 + 1 + 127
    assert publish_bytes(5, 121, 0) == 1 + 2 + 128


def test_topic_length_is_utf8_bytes() -> None:
    assert publish_bytes("é", 0, 0) == 1 + 1 + 2 + 2


def test_bad_qos() -> None:
    with pytest.raises(ValueError):
        publish_bytes("t", 1, 3)


def test_frame_bytes() -> None:
    assert frame_bytes(30) == 30 + 40 + 38
    assert frame_bytes(30, tcpip=0, ethernet=0) == 30
    # PUBACK + TCP/IP = 44 < 46 Ethernet minimum payload -> padded: 46 + 38
    assert PUBACK_BYTES == 4
    assert frame_bytes(PUBACK_BYTES) == 84
    assert frame_bytes(PUBACK_BYTES, ethernet=0) == 44


def test_frame_bytes_segmentation() -> None:
    # 3000 B in 1460 B segments: 1460, 1460, 80 -> 2 * (1500 + 38) + (120 + 38)
    assert frame_bytes(3000, mss=1460) == 3234
    assert frame_bytes(3000) == 3078
    assert frame_bytes(1460, mss=1460) == 1538
