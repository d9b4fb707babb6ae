"""A campaign's primary run: the most typical repeat (hand-computed), whatever the order."""

from __future__ import annotations

import math
from dataclasses import replace
from itertools import permutations
from pathlib import Path

import pytest

from sigma_des.calibrate.campaign import combine
from sigma_des.calibrate.primary import central, primary_run
from tests.calibrate.test_calibrate_campaign import _fit


def test_central_hand_computed() -> None:
    runs = {"r1": {"a": {"aoi_mean": 1.0, "latency_state_mean": 4.0}},
            "r2": {"a": {"aoi_mean": 1.1, "latency_state_mean": 3.0}},
            "r3": {"a": {"aoi_mean": 1.2, "latency_state_mean": 3.1}}}
    # medians 1.1 and 3.1: r1 0.0953 + 0.2549, r2 0 + 0.0328, r3 0.0870 + 0
    assert central(runs) == "r2"
    assert central(runs, ("aoi_mean",)) == "r2"
    assert central(runs, ("latency_state_mean",)) == "r3"
    # a method missing (or NaN) in one run is left out of the comparison
    runs["r2"]["b"] = {"aoi_mean": 100.0, "latency_state_mean": 100.0}
    runs["r1"]["b"] = {"aoi_mean": math.nan, "latency_state_mean": 1.0}
    assert central(runs) == "r2"
    # two runs: both equally far (in log) from their median; the first wins the tie
    assert central({"x": {"a": {"aoi_mean": 1.0}}, "y": {"a": {"aoi_mean": 2.0}}}) == "x"
    with pytest.raises(ValueError):
        central({})


def _run(name: str, lat: float, bundle: bool = False, nodes: int = 20) -> dict[str, object]:
    return {"name": name, "bundle": bundle, "nodes": nodes, "hosts": 2,
            "figures": {"none": {"aoi_mean": 15.0, "latency_state_mean": lat}}}


def test_primary_is_the_typical_repeat_in_any_order() -> None:
    """Three repeats of 20 nodes at 2.2, 1.8 and 2.0 ms: the 2.0 ms one (the median),
    wherever it stands; a bundled run and a per-node run of another size are not
    repeats."""
    runs = [_run("a", 2.2), _run("b", 1.8), _run("c", 2.0), _run("bundle", 2.0, True),
            _run("n60", 2.0, nodes=60)]
    for order in permutations(runs[:3]):
        seq = [runs[3], *order, runs[4]]
        i, rule = primary_run(seq)
        assert seq[i]["name"] == "c"
        assert rule.startswith("the most typical of the 3 per-node runs of 20 nodes")
    # two repeats: the first per-node run; none per node: the first run
    assert primary_run([runs[3], runs[1], runs[0]])[0] == 1
    assert primary_run([runs[4], runs[0], runs[2]])[0] == 0  # n60 is the first setting
    assert primary_run([runs[3], _run("b2", 1.0, True)]) == (0, "the first run (none is per node)")


def test_combine_takes_the_step_time_of_the_typical_repeat(tmp_path: Path) -> None:
    """combine's scenario keys come from the most typical repeat: its seed here."""
    fits = []
    for name, lat, seed in (("r1", 2.4, 1), ("r2", 2.0, 2), ("r3", 1.7, 3)):
        sc, rep, info = _fit(tmp_path, name, [1e-3], False, host_demand=1e-4)
        info["figures"] = {"none": {"aoi_mean": 15.0, "latency_state_mean": lat}}
        fits.append((replace(sc, seed=seed), rep, info))
    for order in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        sc, rep, primary = combine([fits[i] for i in order], tmp_path)
        assert rep["primary_run"] == "r2" and sc.seed == 2
        assert [fits[i][2]["name"] for i in order][primary] == "r2"
        assert "most typical of the 3" in rep["primary_rule"]
