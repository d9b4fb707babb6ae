"""Wire sizes of MQTT 3.1.1 packets and their framing (docs/concepts/model.md, "Network").

Throughput is reported in wire bits, so every packet is counted with all its
overheads:

* MQTT PUBLISH: fixed header byte + remaining-length varint (1–4 bytes) + topic
  length (2) + topic + packet identifier (2, QoS >= 1 only) + payload.
* PUBACK: 4 bytes (fixed header, remaining length 2, packet identifier).
* TCP/IP: 40 bytes (IPv4 20 + TCP 20, no options).
* Ethernet: 38 bytes = 14 header (MACs, EtherType) + 4 FCS + 8 preamble/SFD + 12
  inter-frame gap (the gap is idle time on the wire, counted as bytes because it
  occupies link capacity). The Ethernet payload (IP packet) is padded to its
  46-byte minimum, so the smallest frame costs 84 bytes of wire time.

Each MQTT packet is assumed to travel in its own TCP segment (states are tiny);
pass ``mss`` to :func:`frame_bytes` to count segmentation of larger packets.
"""

from __future__ import annotations

__all__ = [
    "ETHERNET_BYTES",
    "ETHERNET_MIN_PAYLOAD",
    "MAX_REMAINING_LENGTH",
    "PUBACK_BYTES",
    "TCPIP_BYTES",
    "frame_bytes",
    "payload_bytes",
    "publish_bytes",
    "remaining_length_bytes",
]

#: MQTT PUBACK: 0x40, remaining length 2, packet identifier (2).
PUBACK_BYTES = 4
#: IPv4 (20) + TCP (20) headers without options.
TCPIP_BYTES = 40
#: Ethernet header 14 + FCS 4 + preamble/SFD 8 + inter-frame gap 12.
ETHERNET_BYTES = 38
#: Minimum Ethernet payload; shorter IP packets are padded to it.
ETHERNET_MIN_PAYLOAD = 46
#: Largest value the MQTT remaining-length varint can encode (4 bytes).
MAX_REMAINING_LENGTH = 268_435_455


def remaining_length_bytes(n: int) -> int:
    """Size of the MQTT remaining-length varint encoding ``n`` (1–4 bytes).

    Raises:
        ValueError: if ``n`` is negative or above :data:`MAX_REMAINING_LENGTH`.
    """
    if n < 0 or n > MAX_REMAINING_LENGTH:
        raise ValueError(f"remaining length must be in [0, {MAX_REMAINING_LENGTH}], got {n}")
    if n < 128:
        return 1
    if n < 16_384:
        return 2
    if n < 2_097_152:
        return 3
    return 4


def publish_bytes(topic: str | int, payload: int, qos: int) -> int:
    """Size of an MQTT PUBLISH packet.

    Args:
        topic: the topic name, or its length in bytes (UTF-8).
        payload: payload size in bytes.
        qos: 0, 1 or 2 (QoS >= 1 adds a 2-byte packet identifier).

    Returns:
        ``1 + varint(remaining) + remaining`` with
        ``remaining = 2 + topic_len + (2 if qos >= 1) + payload``.
    """
    topic_len = len(topic.encode("utf-8")) if isinstance(topic, str) else int(topic)
    if topic_len < 0 or payload < 0:
        raise ValueError("topic length and payload must be >= 0")
    if qos not in (0, 1, 2):
        raise ValueError(f"qos must be 0, 1 or 2, got {qos}")
    remaining = 2 + topic_len + (2 if qos >= 1 else 0) + payload
    return 1 + remaining_length_bytes(remaining) + remaining


def frame_bytes(
    mqtt_bytes: int,
    tcpip: int = TCPIP_BYTES,
    ethernet: int = ETHERNET_BYTES,
    mss: int | None = None,
) -> int:
    """Wire bytes of an MQTT packet with TCP/IP and Ethernet framing.

    Args:
        mqtt_bytes: size of the MQTT packet.
        tcpip: TCP/IP header bytes per segment (default 40).
        ethernet: Ethernet overhead per frame (default 38, see the module doc);
            when > 0 the IP packet is padded to 46 bytes.
        mss: if given, the packet is split into ``ceil(mqtt_bytes / mss)``
            segments, each with its own headers; by default one segment.

    Returns:
        Total bytes occupying the link.
    """
    if mqtt_bytes < 0:
        raise ValueError(f"mqtt_bytes must be >= 0, got {mqtt_bytes}")
    if mss is not None and mss <= 0:
        raise ValueError(f"mss must be > 0, got {mss}")
    if mss is None or mqtt_bytes <= mss:
        sizes = [mqtt_bytes]
    else:
        full, rest = divmod(mqtt_bytes, mss)
        sizes = [mss] * full + ([rest] if rest else [])
    total = 0
    for size in sizes:
        ip = size + tcpip
        if ethernet > 0:
            ip = max(ip, ETHERNET_MIN_PAYLOAD)
        total += ip + ethernet
    return total


def payload_bytes(bits: int) -> int:
    """Bytes needed for a payload of ``bits`` bits (``ceil(bits / 8)``)."""
    if bits < 0:
        raise ValueError(f"bits must be >= 0, got {bits}")
    return (bits + 7) // 8
