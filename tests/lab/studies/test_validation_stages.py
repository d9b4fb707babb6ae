"""The stage decomposition's per-frame figures (``sigma_lab.studies.validation.stages``),
on two hand-made frames."""

from __future__ import annotations

import pandas as pd
import pytest
from sigma_lab.studies.validation.stages import frame_stats


def test_frame_stats_by_hand() -> None:
    """Frame 0: published 1 ms apart, received 2 ms apart (latencies 2, 3, 4, 5 ms);
    frame 1: published 0.5 ms apart, each received 1 ms later, rows out of order."""
    s = pd.DataFrame({
        "frame": [0, 0, 0, 0, 1, 1, 1, 1],
        "t_send": [0.0, 0.001, 0.002, 0.003, 0.0115, 0.010, 0.011, 0.0105],
        "t_recv": [0.002, 0.004, 0.006, 0.008, 0.0125, 0.011, 0.012, 0.0115],
    })
    st = frame_stats(s)
    assert st["lat"] == pytest.approx(18.0 / 8.0)
    assert st["first"] == pytest.approx((2.0 + 1.0) / 2.0)
    assert [st[f"q{q}"] for q in (1, 2, 3, 4)] == pytest.approx([1.5, 2.0, 2.5, 3.0])
    assert st["send"] == pytest.approx((3.0 + 1.5) / 2.0)
    assert st["recv"] == pytest.approx((6.0 + 1.5) / 2.0)
