"""The bundle draw keys (net/bundlekeys.py): ordinals counted per channel, (kind, index)
and distinct first record, hand-computed."""

from __future__ import annotations

import pytest

from sigma_des.net.bundlekeys import BUNDLE_SLOTS, BundleKeys, first_nodes
from sigma_des.net.kinds import COMMAND, REPUBLISH, STATE

S = BUNDLE_SLOTS


def test_a_sequence_of_first_records_on_two_channels() -> None:
    """Channel 0 (its host's first node 0) and channel 1 (first node 3)."""
    k = BundleKeys()
    seq = [
        # (channel, channel subject, first record) -> key
        ((0, 0, STATE, 2, 5), (STATE, 0, 5 * S)),  # frame 5's first bundle of channel 0
        ((0, 0, STATE, 0, 5), (STATE, 0, 5 * S + 1)),  # its second
        ((1, 3, STATE, 3, 5), (STATE, 3, 5 * S)),  # channel 1 counts on its own
        ((0, 0, STATE, 1, 5), (STATE, 0, 5 * S + 2)),  # channel 0's third of frame 5
        ((0, 0, STATE, 0, 5), (STATE, 0, 5 * S + 1)),  # a duplicate: its earlier key
        ((0, 0, STATE, 0, 6), (STATE, 0, 6 * S)),  # a new frame starts at 0
        ((0, 0, REPUBLISH, 2, 5), (REPUBLISH, 0, 5 * S)),  # kinds counted apart
        ((0, 0, COMMAND, 1, 5), (COMMAND, 0, 5 * S)),
        ((0, 0, COMMAND, 2, 5), (COMMAND, 0, 5 * S + 1)),
        ((1, 3, STATE, 4, 5), (STATE, 3, 5 * S + 1)),
        ((0, 0, STATE, 2, 5), (STATE, 0, 5 * S)),  # frame 5 again, ordinal 0 again
        ((0, 0, STATE, 2, 6), (STATE, 0, 6 * S + 1)),
    ]
    assert [k.key(*args) for args, _want in seq] == [want for _args, want in seq]


def test_ordinal_is_capped_at_the_last_slot() -> None:
    k = BundleKeys()
    got = [k.ordinal(0, STATE, s, 7) for s in range(S + 5)]
    assert got == [*range(S), S - 1, S - 1, S - 1, S - 1, S - 1]
    assert k.ordinal(0, STATE, 500, 7) == 500  # one seen before the cap keeps its slot
    assert k.ordinal(0, STATE, S + 2, 7) == S - 1
    assert k.key(0, 0, STATE, S + 9, 7) == (STATE, 0, 7 * S + S - 1)  # below 8 * S


def test_pruning_keeps_the_newest_indices_of_each_channel_and_kind() -> None:
    k = BundleKeys(groups=2)
    assert [k.ordinal(0, STATE, 10, 1), k.ordinal(0, STATE, 10, 2),
            k.ordinal(0, STATE, 11, 2)] == [0, 0, 1]
    # other kinds and channels have room of their own: frames 1 and 2 stay remembered
    for i in (7, 8, 9):
        assert k.ordinal(0, COMMAND, 10, i) == 0
        assert k.ordinal(1, STATE, 10, i) == 0
    assert k.ordinal(0, STATE, 11, 1) == 1
    # a third index of (channel 0, STATE) forgets the oldest, 1; 2 stays
    assert k.ordinal(0, STATE, 10, 3) == 0
    assert k.ordinal(0, STATE, 11, 2) == 1
    assert k.ordinal(0, STATE, 12, 2) == 2
    # index 1 starts over (node 11 had ordinal 1 there) and forgets 2 in turn
    assert k.ordinal(0, STATE, 11, 1) == 0
    assert k.ordinal(0, STATE, 12, 2) == 0
    # the COMMAND indices kept their own newest two: 8 and 9 (7 was forgotten)
    assert [k.ordinal(0, COMMAND, 11, i) for i in (8, 9)] == [1, 1]
    assert k.ordinal(0, COMMAND, 11, 7) == 0


def test_no_groups_is_refused() -> None:
    with pytest.raises(ValueError, match="groups must be >= 1"):
        BundleKeys(groups=0)


def test_first_nodes_are_each_hosts_lowest_node() -> None:
    assert first_nodes([1, 0, 1, 0, 2]) == {1: 0, 0: 1, 2: 4}
    assert first_nodes([0, 0, 0, 1, 1, 1]) == {0: 0, 1: 3}
