"""BiDES frame spread: excluded slots are shown at the aligned frame (issue 9.3)."""

from __future__ import annotations

import pytest

from sigma_des import compare
from tests.conftest import tiny

CRASH = {"faults": [{"kind": "crash", "node": 2, "start": 0.3}]}


@pytest.mark.parametrize("engine", ["events", "cohort"])
def test_crashed_node_is_extrapolated_to_the_aligned_frame(engine: str) -> None:
    """Node 2 dies at 0.3 s; lag exclusion leaves it out and extrapolates it: every
    render tick still shows one frame for everyone."""
    m = compare(tiny(engine=engine, **CRASH), ["bides"], progress=False).methods["bides"]
    assert m["extrapolated_frac"] > 0.2  # node 2 of 3 for most of the window
    assert m["spread_max"] == 0.0
    assert m["off_frame_frac"] == 0.0


def test_without_exclusion_a_wrapped_ring_shows_newer_frames() -> None:
    """Exclusion off: the dead node holds F at its last frame; once the live nodes'
    rings (30 frames) have moved past F, their oldest newer state is shown at its own
    frame: the documented case of a non-zero spread, counted in off_frame_frac."""
    sc = tiny(bides__lag_exclusion=False, bides__adaptation=False, **CRASH)
    m = compare(sc, ["bides"], progress=False).methods["bides"]
    assert m["spread_max"] > 0
    # the two live nodes of three are off the aligned frame after the ring wrapped
    assert 0.0 < m["off_frame_frac"] <= 2.0 / 3.0
    assert m["extrapolated_frac"] == 0.0
