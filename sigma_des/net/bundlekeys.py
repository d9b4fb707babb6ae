"""The draw key of a bundled PUBLISH, one rule for the simulation and live mode.

A bundle (``deployment.bundle``: a host's states of one loop turn, or the server's
commands of one tick to one host, as one PUBLISH) is keyed for its random draws
(loss, latency, broker service) not by its first record but by its place among the
bundles of its host: bundle ``j`` of one ``(kind, index)`` (a frame, a re-request, a
tick) on one host's connection gets the key ``(kind, s_h, index · BUNDLE_SLOTS + j)``,
``s_h`` the host's first (lowest) node. The simulation and a live run split a host's
frame into bundles differently (which records land in which loop turn differs), so a
key of the first record would give the two different draws; with this key "the j-th
bundle of frame f of host h" draws the same whatever records each side packs into it,
and a live run loses the same bundles as its simulation (:mod:`sigma_des.live.shim`
takes the simulation's own loss draws).

``j`` counts the distinct first records ``(kind, subject, index)`` seen so far with that
``(kind, index)`` on that channel: a first record seen again (a QoS 1 duplicate, a
redelivery) gets its earlier ``j`` back. Sender and receiver count on their own
(:class:`BundleKeys` instances apart): a receiver that never got a bundle, lost for
good (QoS 0, or past ``max_retries``), counts the later ones one lower; the simulation
counts that too, at the broker's fan-out, as live counts at receipt. Nothing here is
random or depends on the clock: the keys follow from the order of the first records.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence

__all__ = ["BUNDLE_GROUPS", "BUNDLE_SLOTS", "BundleKeys", "first_nodes"]

#: Bundles of one ``(kind, index)`` on one channel keyed apart: the key's index is
#: ``index · BUNDLE_SLOTS + j`` (later bundles share the last slot, ``BUNDLE_SLOTS - 1``).
BUNDLE_SLOTS = 1024
#: Indices remembered per channel and kind (the oldest forgotten first): enough for
#: seconds of frames, so a late duplicate still finds its bundle's ordinal.
BUNDLE_GROUPS = 256

#: one channel's groups of one kind: index -> {first record's subject: ordinal}
_Groups = OrderedDict[int, dict[int, int]]


class BundleKeys:
    """Ordinals and draw keys of bundles, counted per channel (one host's connection).

    Args:
        groups: indices remembered per channel and kind (:data:`BUNDLE_GROUPS`).
    """

    __slots__ = ("_groups", "_seen")

    def __init__(self, groups: int = BUNDLE_GROUPS) -> None:
        if groups < 1:
            raise ValueError(f"groups must be >= 1, got {groups}")
        self._groups = groups
        self._seen: dict[tuple[int, int], _Groups] = {}

    def ordinal(self, channel: int, kind: int, subject: int, index: int) -> int:
        """The place of the bundle whose first record is ``(kind, subject, index)`` among
        the bundles of ``(kind, index)`` on ``channel``: the number of distinct first
        records seen there before it (its earlier ordinal if seen already), at most
        ``BUNDLE_SLOTS - 1``.

        Args:
            channel: which connection the bundle travels (a host's).
            kind: the first record's message kind.
            subject: the first record's node.
            index: the first record's frame, re-request index or tick.
        """
        per_kind = self._seen.get((channel, kind))
        if per_kind is None:
            per_kind = self._seen[channel, kind] = OrderedDict()
        group = per_kind.get(index)
        if group is None:
            group = per_kind[index] = {}
            if len(per_kind) > self._groups:
                per_kind.popitem(last=False)
        j = group.get(subject)
        if j is None:
            j = group[subject] = min(len(group), BUNDLE_SLOTS - 1)
        return j

    def key(self, channel: int, channel_subject: int, kind: int, subject: int, index: int
            ) -> tuple[int, int, int]:
        """The bundle's draw key ``(kind, channel_subject, index · BUNDLE_SLOTS + j)``.

        Args:
            channel: which connection the bundle travels (a host's).
            channel_subject: the subject of the key: the host's first (lowest) node.
            kind: the first record's message kind.
            subject: the first record's node.
            index: the first record's frame, re-request index or tick.
        """
        j = self.ordinal(channel, kind, subject, index)
        return kind, channel_subject, index * BUNDLE_SLOTS + j


def first_nodes(host_of: Sequence[int]) -> dict[int, int]:
    """Each host's first (lowest) node, the subject of its bundles' keys (the
    simulation's id of a host's MQTT client).

    Args:
        host_of: the host of each node.
    """
    first: dict[int, int] = {}
    for i, h in enumerate(host_of):
        first.setdefault(int(h), i)
    return first
