"""Integer keys a run cannot honour are refused on load, naming the key and its range."""

from __future__ import annotations

import pytest

from sigma_des import compare, load
from sigma_des.cli import main

HUGE = 9223372036854775807


@pytest.mark.parametrize(("key", "allowed"), [
    ("cores_per_host", "must be in 1..4096"),
    ("payload_bits", "must be in 1..1073741824 bits"),
    ("trigger_payload_bits", "must be in 0..1073741824 bits"),
    ("commands.payload_bits", "must be in 0..1073741824 bits"),
    ("net.tcpip_bytes", "must be in [0, 65535] bytes"),
    ("net.ethernet_bytes", "must be in [0, 65535] bytes"),
])
def test_a_huge_integer_is_refused_with_its_range(
        key: str, allowed: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", f"{key}={HUGE}"]) == 2
    err = capsys.readouterr().err
    assert f"{key}: {allowed}" in err and "Traceback" not in err


def test_the_largest_values_run() -> None:
    sc = load(None, ["nodes=2", "hosts=1", "duration=0.3", "warmup=0.1",
                     "cores_per_host=4096", "payload_bits=1073741824",
                     "trigger_payload_bits=1073741824", "commands.payload_bits=1073741824",
                     "net.tcpip_bytes=65535", "net.ethernet_bytes=65535"])
    res = compare(sc, ["none"], progress=False)
    # 100 Hz triggers of 2^30 bits to 2 nodes: the wire carries them (about 214.7 Gbit/s)
    assert res.metric("none", "throughput_mbps") > 1e5
