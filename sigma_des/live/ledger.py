"""Wire-byte accounting of one live process's access link (both directions).

Every PUBLISH a process sends or receives is counted with the same framing the
DES counts (``sigma_des.net.wire``: MQTT header, topic, packet id for QoS 1,
payload, TCP/IP and Ethernet), plus the PUBACK going the other way for QoS 1, if
the message was published inside the metrics window ``[warmup, duration)``.
"""

from __future__ import annotations

from sigma_des.config import Scenario
from sigma_des.net.wire import PUBACK_BYTES, frame_bytes, publish_bytes

__all__ = ["Ledger", "publishes"]


class Ledger:
    """Byte and packet counts of link ``name`` (``<name>.up`` and ``<name>.down``)."""

    def __init__(self, sc: Scenario, name: str) -> None:
        self.name = name
        self.w0 = sc.warmup
        self.end = sc.duration
        self.tcpip = sc.net.tcpip_bytes
        self.eth = sc.net.ethernet_bytes
        self.ack = frame_bytes(PUBACK_BYTES, self.tcpip, self.eth)
        self.bytes = {"up": 0, "down": 0}
        self.packets = {"up": 0, "down": 0}
        self._sizes: dict[tuple[int, int, int], int] = {}

    def _wire(self, topic_len: int, size: int, qos: int) -> int:
        key = (topic_len, size, qos)
        b = self._sizes.get(key)
        if b is None:
            b = self._sizes[key] = frame_bytes(
                publish_bytes(topic_len, size, qos), self.tcpip, self.eth
            )
        return b

    def _count(self, t_send: float, first: str, second: str, topic_len: int, size: int,
               qos: int) -> None:
        if not self.w0 <= t_send < self.end:
            return
        self.bytes[first] += self._wire(topic_len, size, qos)
        self.packets[first] += 1
        if qos >= 1:
            self.bytes[second] += self.ack
            self.packets[second] += 1

    def sent(self, t_send: float, topic_len: int, size: int, qos: int) -> None:
        """This process published a message (its PUBACK comes back down)."""
        self._count(t_send, "up", "down", topic_len, size, qos)

    def received(self, t_send: float, topic_len: int, size: int, qos: int) -> None:
        """This process received a message (it sends the PUBACK up)."""
        self._count(t_send, "down", "up", topic_len, size, qos)

    def as_dict(self) -> dict[str, list[int]]:
        """``{"<name>.up": [bytes, packets], "<name>.down": [...]}``."""
        return {f"{self.name}.{d}": [self.bytes[d], self.packets[d]] for d in ("up", "down")}


def publishes(links: dict[str, list[int]], qos: int) -> int:
    """PUBLISH messages (sent + received) behind a process's :meth:`Ledger.as_dict`
    counts: every PUBLISH is one packet, plus one PUBACK going the other way at QoS 1."""
    packets = sum(int(v[1]) for v in links.values())
    return packets // (1 + qos)
