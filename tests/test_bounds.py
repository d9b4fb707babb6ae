"""Runaway and meaningless values are refused with their range (issue 9.8, 9.9)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sigma_des.budget as budget
from sigma_des import ConfigError, compare, load
from sigma_des.cli import main
from sigma_des.sweep.grid import MAX_SEEDS, parse_grid_args, parse_seeds
from sigma_des.sweep.runner import Sweep

BIG = st.floats(min_value=1.0, max_value=1e300, allow_nan=False) | st.just(math.inf)

#: (override template, key, allowed upper bound, words of the message)
BOUNDED = [
    ("f_trig={}", "f_trig", 10_000.0, "(0, 10000] Hz"),
    ("f_align={}", "f_align", 10_000.0, "(0, 10000] Hz"),
    ("f_render={}", "f_render", 10_000.0, "(0, 10000] Hz"),
    ("duration={}", "duration", 86_400.0, "(0, 86400] s"),
]


def _bad(override: str) -> ConfigError:
    with pytest.raises(ConfigError) as ei:
        load(None, [override])
    return ei.value


@pytest.mark.parametrize(("tmpl", "key", "hi", "words"), BOUNDED)
@settings(max_examples=30, deadline=None)
@given(excess=BIG)
def test_rates_and_duration_are_bounded(
    tmpl: str, key: str, hi: float, words: str, excess: float
) -> None:
    v = hi * (1 + excess) if math.isfinite(excess) else math.inf
    if math.isinf(v):
        e = _bad(tmpl.format("inf"))
    else:
        e = _bad(tmpl.format(repr(v)))
    assert e.key == key and (words in e.reason or "finite" in e.reason)


@settings(max_examples=30, deadline=None)
@given(st.integers(100_001, 10**15))
def test_history_frames_bounded(h: int) -> None:
    e = _bad(f"history_frames={h}")
    assert e.key == "history_frames" and "16..100000" in e.reason


@settings(max_examples=30, deadline=None)
@given(st.integers(101, 10**12))
def test_max_retries_bounded(r: int) -> None:
    e = _bad(f"net.max_retries={r}")
    assert e.key == "net.max_retries" and "[0, 100]" in e.reason


@settings(max_examples=30, deadline=None)
@given(st.floats(1000.0, 1e300, exclude_min=True) | st.just(math.inf))
def test_slow_factor_bounded(f: float) -> None:
    v = "inf" if math.isinf(f) else repr(f)
    e = _bad(f"faults=[{{kind='slow', node=1, start=1.0, factor={v}}}]")
    assert e.key == "faults[0].factor" and "[1, 1000]" in e.reason


@settings(max_examples=30, deadline=None)
@given(st.floats(3600.0, 1e300, exclude_min=True) | st.just(math.inf))
def test_degrade_delay_bounded(d: float) -> None:
    v = "inf" if math.isinf(d) else repr(d)
    e = _bad(f"faults=[{{kind='degrade', host=1, start=1.0, extra_delay={v}}}]")
    assert e.key == "faults[0].extra_delay" and "[0, 3600] s" in e.reason


@pytest.mark.parametrize("kind", ["crash", "slow", "drop"])
def test_infinite_start_is_reported_against_start(kind: str) -> None:
    e = _bad(f"faults=[{{kind='{kind}', node=1, start=inf, frame=3}}]")
    assert e.key == "faults[0].start" and "finite" in e.reason


def test_grid_error_names_the_right_parameter() -> None:
    with pytest.raises(ConfigError) as ei:
        Sweep(load(None, ["nodes=2"]), parse_grid_args(["methods=none,bides"]), None, 1,
              ":memory:")
    assert "methods=..." in ei.value.reason and "methodss" not in ei.value.reason


@settings(max_examples=30, deadline=None)
@given(st.integers(MAX_SEEDS + 1, 10**18), st.integers(0, 1000))
def test_seed_ranges_are_bounded_before_they_are_built(count: int, first: int) -> None:
    for text in (str(count), f"{first}..{first + count - 1}"):
        with pytest.raises(ConfigError) as ei:
            parse_seeds(text)
        assert ei.value.key == "seeds" and f"at most {MAX_SEEDS}" in ei.value.reason
    assert len(parse_seeds(f"{first}..{first + MAX_SEEDS - 1}")) == MAX_SEEDS


def test_memory_estimate_hand_case() -> None:
    """3 nodes, H = 64, no bides, no commands, no fidelity, window 0.8 s at 25 Hz
    render and 100 Hz triggers."""
    sc = load(None, ["nodes=3", "history_frames=64", "methods=['none']", "duration=1.0",
                     "warmup=0.2", "f_render=25", "commands.enabled=false",
                     "fidelity.enabled=false"])
    history = 64 * 3 * 12 * 8
    samples = 20 * 3 * 2 * 8
    latencies = 160 * 3 * 32
    assert budget.estimate_bytes(sc) == history + samples + latencies + 3 * 4096
    assert budget.estimate_bytes(sc, 2) == 2 * budget.estimate_bytes(sc)


def test_memory_refusal_and_force(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(budget, "available_bytes", lambda: 1000)
    sets = ["--set", "nodes=2", "--set", "duration=0.2", "--set", "warmup=0.1", "--set",
            "fidelity.enabled=false", "--methods", "none", "--no-progress"]
    assert main(["compare", *sets]) == 2
    err = capsys.readouterr().err
    assert "memory: this run needs about" in err and "--force" in err
    assert main(["compare", *sets, "--force"]) == 0
    res = compare(load(None, ["nodes=2", "duration=0.2", "warmup=0.1"]), ["none"],
                  progress=False, force=True)
    assert res.methods["none"]["trigger_rate_hz"] == 100.0
