"""Wire-byte ledger (hand-computed frames) and the fan-out slope fit (exact line)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sigma_des import Scenario
from sigma_des.calibrate.fit import delivery_floor, fanout_slope
from sigma_des.live.ledger import Ledger


def test_ledger_counts_framing_and_pubacks_in_the_window() -> None:
    led = Ledger(Scenario(nodes=2, hosts=1, duration=2.0, warmup=1.0), "host0")
    led.sent(1.5, topic_len=20, size=85, qos=1)
    led.sent(0.5, topic_len=20, size=85, qos=1)  # before the window: not counted
    led.received(1.2, topic_len=10, size=33, qos=0)
    # PUBLISH = 1 + 1 + (2 + 20 + 2 + 85) = 111; + TCP/IP 40 + Ethernet 38 = 189
    # PUBACK = 4 + 40 -> padded to 46, + 38 = 84; QoS 0 trigger 1+1+(2+10+33)=47 +78 = 125
    assert led.as_dict() == {"host0.up": [189, 1], "host0.down": [84 + 125, 2]}


def test_fanout_slope_recovers_an_exact_line() -> None:
    rows = []
    for f in range(5):
        for pos in range(4):
            rows.append({"frame": f, "t_send": f * 0.01,
                         "t_recv": f * 0.01 + 0.001 + 0.0002 * pos})
    a, b = fanout_slope(pd.DataFrame(rows).sample(frac=1.0, random_state=0))
    assert a == pytest.approx(0.001, abs=1e-12)
    assert b == pytest.approx(0.0002, abs=1e-12)
    one = pd.DataFrame([{"frame": 0, "t_send": 0.0, "t_recv": 0.003}])
    assert fanout_slope(one) == (pytest.approx(0.003), 0.0)


def test_delivery_floor_is_the_low_quantile_of_consecutive_gaps() -> None:
    rows = []
    for f in range(40):  # 3 receivers: gaps 0.0001 exactly, plus a late wake-up on 1 in 4
        late = 0.002 if f % 4 == 0 else 0.0
        for pos in range(3):
            rows.append({"frame": f, "t_recv": f * 0.01 + 0.0001 * pos + (late if pos else 0)})
    df = pd.DataFrame(rows)
    assert delivery_floor(df) == pytest.approx(0.0001, abs=1e-12)
    gaps = np.array([0.0021] * 10 + [0.0001] * 70)
    assert delivery_floor(df, q=0.99) == pytest.approx(np.quantile(gaps, 0.99))
    assert delivery_floor(df.iloc[:1]) == 0.0


def test_fanout_and_floor_take_a_trigger_within_its_method() -> None:
    # two methods' frame 0 (each method's clock starts at 0): the receivers of one
    # trigger are 1 ms apart and each later one waited 1 ms more. Mixed by frame alone
    # the four receipts interleave (gaps 0.1, 0.9, 0.1 ms; positions 0..3)
    rows = [("a", 0, 0.0, 0.0020), ("a", 0, 0.0, 0.0030),
            ("b", 0, 0.0, 0.0021), ("b", 0, 0.0, 0.0031)]
    df = pd.DataFrame(rows, columns=["method", "frame", "t_send", "t_recv"])
    a, b = fanout_slope(df)
    assert b == pytest.approx(0.001) and a == pytest.approx(0.00205)
    assert delivery_floor(df) == pytest.approx(0.001)
    # without a method column every row of a frame is one trigger's, as before
    assert delivery_floor(df.drop(columns="method")) == pytest.approx(0.0001)
