"""Helpers of the live tests: they need the mosquitto executable and skip (saying why)
only when it is absent; the small live scenario."""

from __future__ import annotations

import pytest

from sigma_des import load
from sigma_des.config import Scenario
from sigma_des.live.broker import find_mosquitto

needs_mosquitto = pytest.mark.skipif(
    find_mosquitto() is None, reason="mosquitto is not installed (apt-get install mosquitto)"
)

#: A small live scenario: 4 nodes on 2 hosts, 1.5 s.
LIVE_SETS = ["nodes=4", "hosts=2", "duration=1.5", "warmup=0.3"]


def live_scenario(*extra: str) -> Scenario:
    """The small live scenario with ``extra`` overrides."""
    return load(None, LIVE_SETS + list(extra))
