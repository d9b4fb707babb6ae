"""A run that delivered no state says why; a delay beyond any run is refused on load."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from sigma_des import compare, load
from sigma_des.cli import main
from sigma_des.empty import empty_notes

SMALL = ["nodes=4", "hosts=1", "duration=0.5", "warmup=0.1"]


def test_a_latency_longer_than_the_run_is_named(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["compare", *(a for s in SMALL for a in ("--set", s)), "--set",
               "net.host_link.latency.value=50", "--methods", "none", "--no-progress",
               "--no-plots", "--out", str(tmp_path)])
    assert rc == 0
    err = capsys.readouterr().err
    assert ("warning: none: no state was delivered inside the measured window (0.1 to 0.5 s, "
            "0.4 s), so its AoI and latency are NaN; the largest mean delay is "
            "net.host_link.latency = 50 s") in err
    summ = json.loads((tmp_path / "summary.json").read_text())
    assert math.isnan(summ["methods"]["none"]["aoi_mean"] or math.nan)
    assert summ["warnings"] == [err.split("sigma-des: warning: ")[1].strip()]


def test_a_run_that_measured_something_has_no_note() -> None:
    res = compare(load(None, SMALL), ["none"], progress=False)
    assert res.warnings() == [] and "warnings" not in res.summary()
    sc = load(None, [*SMALL, "broker.publish_service.value=20"])
    notes = empty_notes(sc, {"none": {"aoi_mean": 3.0}, "hlc": {"aoi_mean": math.nan}})
    assert len(notes) == 1 and notes[0].startswith("hlc: ")
    assert notes[0].endswith("broker.publish_service = 20 s")


@pytest.mark.parametrize("key", ["net.host_link.latency.value", "broker.publish_service.value",
                                 "compute.step_time.mean", "rpc.render_time.std"])
def test_a_delay_beyond_a_million_seconds_is_refused(
        key: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", f"{key}=1e300"]) == 2
    err = capsys.readouterr().err
    assert f"{key}: must be >= 0 and <= 1e+06 s, got 1e+300" in err
    assert "Traceback" not in err


def test_an_empirical_sample_beyond_a_million_seconds_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "d.txt"
    f.write_text("0.001\n2e6\n")
    with pytest.raises(Exception, match=r"d.txt:2: samples must be >= 0 and <= 1e\+06 s"):
        load(None, [f'net.host_link.latency={{dist="empirical", file="{f}"}}'])


def test_a_state_longer_to_serialize_than_the_run_is_named() -> None:
    sc = load(None, [*SMALL, "payload_bits=1073741824", "net.host_link.bandwidth_mbps=1000"])
    (note,) = empty_notes(sc, {"none": {"aoi_mean": math.nan}})
    # 2^30 bits at 1e9 bit/s: 1.07374 s, longer than any delay key
    assert note.endswith("the largest mean delay is payload_bits / net.host_link.bandwidth_mbps "
                         "(a state's serialization) = 1.07374 s")
