"""Which hooks a recording tap overrides (a caller skips building the arguments of the
others: the base tap ignores them)."""

from __future__ import annotations

from sigma_des.events.tap import Tap, records
from sigma_des.record.tap import RecordTap


class _States(Tap):
    def states(self, t_recv, nodes, frames, gens, obs) -> None:  # type: ignore[no-untyped-def]
        self.got = nodes


def test_records_says_which_hooks_a_tap_overrides() -> None:
    assert not records(Tap(), "commands") and not records(Tap(), "states")
    assert records(_States(), "states") and not records(_States(), "commands")
    assert RecordTap.commands is not Tap.commands  # a recording takes the command sends
    assert records(RecordTap.__new__(RecordTap), "commands")
