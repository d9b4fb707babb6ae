"""The memory guard names the key that caused its estimate."""

from __future__ import annotations

import pytest

from sigma_des import budget, load
from sigma_des.cli import main
from sigma_des.errors import ConfigError


def test_the_guard_names_the_largest_term(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(budget, "available_bytes", lambda: 2**28)
    sc = load(None, ["nodes=200", "duration=10", "fidelity.log_rate=10000"])
    terms = budget.estimate_terms(sc)
    key = "fidelity.log_rate 10000 Hz × duration 10 s × nodes 200"
    # (10 s × 10 kHz + 1) samples × 200 nodes × 3 coordinates × 8 bytes, run and ideal run
    assert terms[key] == 2 * 100_001 * 200 * 3 * 8
    assert budget.estimate_bytes(sc) == sum(terms.values())
    with pytest.raises(ConfigError, match=f"most of it for {key} ") as ei:
        budget.check_memory(sc)
    assert ei.value.key == "memory"
    sc = load(None, ["nodes=200000", "history_frames=100000"])
    with pytest.raises(ConfigError, match="most of it for history_frames 100000 × nodes 200000 "):
        budget.check_memory(sc)


def test_a_log_rate_beyond_any_clock_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--set", "fidelity.log_rate=1e300"]) == 2
    assert "fidelity.log_rate: must be in (0, 10000] Hz, got 1e+300" in capsys.readouterr().err
