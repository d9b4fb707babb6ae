"""Alignment and render loops run out of phase with the triggers (issue 9.2)."""

from __future__ import annotations

import pytest

from sigma_des import ConfigError, compare, load
from tests.conftest import tiny

SMALL = ["nodes=20", "duration=2", "warmup=0.5"]


def test_render_phase_shifts_sampled_aoi_by_exactly_the_phase() -> None:
    """Tiny scenario (align = render = 25 Hz): the shown state changes at alignment
    ticks, so rendering delta of a period later adds exactly delta * 40 ms to every
    sample, and the time average does not move."""
    base = compare(tiny(), ["none"], progress=False).methods["none"]
    for delta in (0.25, 0.5):
        m = compare(tiny(render_phase=delta), ["none"], progress=False).methods["none"]
        assert m["aoi_mean"] == pytest.approx(base["aoi_mean"] + delta * 40.0, abs=1e-9)
        assert m["aoi_time_avg"] == base["aoi_time_avg"]
    mid = compare(tiny(render_phase=0.5), ["none"], progress=False).methods["none"]
    assert mid["aoi_mean"] == pytest.approx(mid["aoi_time_avg"], abs=1e-9)


def test_defaults_tell_none_from_lockstep() -> None:
    """With the default phases the command ticks fall while states arrive: none sends
    commands from a mixed frame and flies differently from Lock-Step; with both
    phases 0 (the old defaults) the two flew identically."""
    new = compare(load(None, SMALL), ["none", "lockstep"], progress=False).methods
    assert new["none"]["formation_err_mean"] != new["lockstep"]["formation_err_mean"]
    # the default render phase samples mid-sawtooth: aoi_mean is the time average
    for m in new.values():
        assert abs(m["aoi_mean"] - m["aoi_time_avg"]) < 0.5
    old = compare(
        load(None, [*SMALL, "align_phase=0", "render_phase=0"]), ["none", "lockstep"],
        progress=False,
    ).methods
    assert old["none"]["formation_err_mean"] == old["lockstep"]["formation_err_mean"]


@pytest.mark.parametrize("value", [-0.1, 1.0, 2.5])
def test_phase_out_of_range(value: float) -> None:
    for key in ("align_phase", "render_phase"):
        with pytest.raises(ConfigError) as ei:
            load(None, [f"{key}={value}"])
        assert ei.value.key == key and "[0, 1)" in ei.value.reason
