"""Clock reconciliation (live/clocksync.py) on hand-made exchanges, and placement rules."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sigma_des.errors import ConfigError
from sigma_des.live.clocksync import MAX_DRIFT, ClockBook, Exchange, fit_clock, min_rtt_filter
from sigma_des.live.cluster import check_reachable, correct_rows, parse_scheduler
from sigma_des.live.placement import Pin, Worker, assign, read_placement


def exchange(s1: float, d_up: float, d_down: float, turn: float, a: float, b: float,
             group: int) -> Exchange:
    """The exchange a host with clock ``C_h = a + b C_s`` gives: ping sent at server time
    ``s1``, ``d_up`` s to the host, ``turn`` s there, ``d_down`` s back."""
    s2 = s1 + d_up
    s3 = s2 + turn
    return Exchange(s1, a + b * s2, a + b * s3, s3 + d_down, group)


def test_symmetric_delays_give_offset_and_drift_exactly() -> None:
    rng = np.random.default_rng(1)
    a, b = 1234.5, 1.0 + 100e-6  # 100 ppm fast, 1234.5 s ahead
    ex = [exchange(1000.0 + 0.5 * g + 0.01 * i, d, d, 1e-5, a, b, g)
          for g in range(20) for i, d in enumerate(rng.uniform(2e-4, 5e-3, 3))]
    f = fit_clock(ex)
    assert len(f.mids) == 20  # one kept per burst
    assert f.drift == pytest.approx(b - 1.0, abs=1e-9)
    for s in (1000.0, 1005.0, 1012.0):
        assert f.host_time(s) == pytest.approx(a + b * s, abs=1e-9)
        assert f.server_time(a + b * s) == pytest.approx(s, abs=1e-9)
    # with symmetric paths each exchange's offset is exact: the residual is rounding only
    assert f.residual_rms < 1e-9


def test_asymmetric_delays_stay_within_the_round_trip_bound() -> None:
    rng = np.random.default_rng(7)
    a, b = -42.0, 1.0 - 40e-6
    ex = [exchange(50.0 + 1.0 * g + 0.005 * i, u, d, 2e-5, a, b, g)
          for g in range(12)
          for i, (u, d) in enumerate(rng.exponential(2e-3, (4, 2)) + 1e-4)]
    f = fit_clock(ex)
    for e in min_rtt_filter(ex):  # NTP: the true offset at mid lies within delta / 2
        true = a + (b - 1.0) * e.mid
        assert abs(e.offset - true) <= e.delay / 2 + 1e-12
    bound = f.bound()
    errs = [abs(f.host_time(s) - (a + b * s)) for s in np.linspace(50.0, 61.0, 45)]
    assert 0.0 < max(errs) <= bound
    # the bound is not loose by orders of magnitude: the kept round trips are ~0.5-2 ms
    assert bound < 5e-3


def test_min_rtt_filter_keeps_the_fastest_of_each_burst() -> None:
    ex = [Exchange(0.0, 0.0, 0.0, 0.004, 1), Exchange(0.01, 0.0105, 0.0105, 0.011, 1),
          Exchange(1.0, 1.0, 1.0, 1.003, 2), Exchange(1.01, 1.01, 1.01, 1.012, 2)]
    assert min_rtt_filter(ex) == [ex[1], ex[3]]


def test_short_span_fits_no_drift_and_drift_is_held_at_the_tolerance() -> None:
    # 0.6 s of exchanges cannot resolve drift: offset = mean, bound = mean half delay
    ex = [exchange(10.0 + 0.3 * g, 1e-3, 1e-3 + 4e-4 * g, 0.0, 5.0, 1.0, g) for g in range(3)]
    f = fit_clock(ex)
    assert f.drift == 0.0
    assert f.offset == pytest.approx(5.0 - 2e-4, abs=1e-12)  # mean of (d_up - d_down) / 2
    assert f.bound() == pytest.approx(np.mean([e.delay / 2 for e in ex]))
    # a clock 2000 ppm fast is beyond what crystals do: held at 500 ppm
    ex = [exchange(10.0 + g, 1e-3, 1e-3, 0.0, 0.0, 1.002, g) for g in range(5)]
    assert fit_clock(ex).drift == MAX_DRIFT


def test_negative_latency_is_counted_and_kept_not_clipped() -> None:
    book = ClockBook(2)
    for g in range(2):
        book.add(1, exchange(100.0 + 0.1 * g, 1e-3, 1e-3, 0.0, 7.0, 1.0, g))
    assert book.start(100.0, [1]) == {1: pytest.approx(107.0)}
    assert book.latency(1, 0.5, 0.501) == pytest.approx(0.5)
    assert book.latency(1, 0.5, 0.499) == pytest.approx(0.5)  # kept as it is
    assert book.negative == [0, 1]
    # a host's trigger row received (host clock) before it was sent (server clock)
    vals = np.array([[1, -1, 3, 0.30, 0.2995, np.nan, np.nan, 0.0],
                     [1, 2, 3, 0.31, np.nan, 0.3, 0.0, 0.0]])
    out = correct_rows(np.array(["trigger", "state_pub"]), vals, 1, book)
    assert out[0, 4] == pytest.approx(0.2995) and out[1, 5] == pytest.approx(0.3)
    assert book.negative == [0, 2]
    rep = book.report(1.0)
    assert rep["1"]["negative_latencies"] == 2 and rep["0"]["exchanges"] == 0
    assert rep["1"]["offset_s"] == pytest.approx(7.0)


W = [Worker("tcp://10.0.0.2:1", "b"), Worker("tcp://10.0.0.1:1", "a",
                                                {"gpu": 1.0})]


def test_spread_pack_and_a_placement_file(tmp_path: Path) -> None:
    a, b = W[1].address, W[0].address
    assert assign(3, W, "spread") == [Pin(a), Pin(b), Pin(a)]  # sorted by name
    assert assign(3, W, "pack") == [Pin(a)] * 3
    f = tmp_path / "p.toml"
    f.write_text('default = "pack"\n[hosts]\n1 = "b"\n2 = { resources = { gpu = 1 } }\n')
    assert assign(4, W, read_placement(str(f))) == [Pin(a), Pin(b),
                                                    Pin(resources={"gpu": 1.0}), Pin(a)]


@pytest.mark.parametrize("body, words", [
    ('[hosts]\n0 = "c"\n', "no worker named or at 'c'"),
    ('[hosts]\n5 = "a"\n', "host '5' is not a host index in 0..1"),
    ('[hosts]\n0 = { resources = { fpga = 1 } }\n', "no worker has resources"),
    ('default = "scatter"\n', "default must be 'spread' or 'pack'"),
    ('nodes = 3\n', "unknown key 'nodes'"),
    ('[hosts\n', "not readable as TOML"),
])
def test_bad_placement_names_the_option(tmp_path: Path, body: str, words: str) -> None:
    f = tmp_path / "p.toml"
    f.write_text(body)
    with pytest.raises(ConfigError, match="--placement") as e:
        assign(2, W, read_placement(str(f)))
    assert words in str(e.value)


def test_scheduler_address_forms() -> None:
    assert parse_scheduler("tcp://10.0.0.5:8786") == ("10.0.0.5", 8786)
    assert parse_scheduler("node-a:8786") == ("node-a", 8786)
    for bad in ("tcp://x", "http://a:1", "a:0", "a:99999"):
        with pytest.raises(ConfigError, match="--scheduler"):
            parse_scheduler(bad)


def test_our_own_broker_needs_every_worker_on_loopback() -> None:
    check_reachable([Worker("tcp://127.0.0.1:40000", "a")], own_broker=True)
    far = [Worker("tcp://127.0.0.1:40000", "a"), Worker("tcp://10.0.0.9:40000", "rack-b")]
    check_reachable(far, own_broker=False)  # --broker given: the user's broker
    with pytest.raises(ConfigError, match="--broker: worker rack-b"):
        check_reachable(far, own_broker=True)
