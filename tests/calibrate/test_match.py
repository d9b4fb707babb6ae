"""The hop-latency and CPU match's steps (sigma_des/calibrate/match.py), by hand, and
the bundled run's match on a small DES."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sigma_des import load
from sigma_des.api import run_method
from sigma_des.calibrate.match import (
    K_MAX,
    K_MIN,
    MATCH_TOL,
    SIDE_MAX,
    _first,
    _live_cpu,
    _next_scale,
    _pairs,
    match_bundled,
)
from sigma_des.calibrate.target import prepare
from sigma_des.config import Scenario
from sigma_des.net.latency import Dist

MEAN = {"hop_up": 1e-3}


def _step(tried: list[tuple[float, float]], live: float) -> float:
    k, des = tried[-1]
    return _next_scale(tried, live, _first("hop_up", k, live, des, MEAN))


def test_first_step_spreads_the_difference_over_two_hops() -> None:
    # DES 5 ms, live 4 ms, a hop of 1 ms on average: each hop 0.5 ms shorter -> k = 0.5
    assert _step([(1.0, 5.0)], 4.0) == pytest.approx(0.5)
    assert _step([(1.0, 5.0)], 1.0) == K_MIN  # never below the floor
    assert _step([(1.0, 5.0)], 99.0) == K_MAX


def test_an_all_zero_hop_is_not_scaled() -> None:
    """A direction whose samples are all 0 (a mean hop of 0: loopback under load) keeps
    its scale: no scale moves it, and the step must not divide by it."""
    assert _first("hop_down", 1.0, 4.0, 5.0, {"hop_down": 0.0}) == 1.0


def test_a_bracket_is_closed_by_the_secant_through_its_nearest_pairs() -> None:
    # pairs on both sides of live = 4: (0.5, 3) below, (1, 5) above -> 0.75
    assert _step([(1.0, 5.0), (0.5, 3.0)], 4.0) == pytest.approx(0.75)
    # a farther pair on one side is not used: (0.2, 1) is below but (0.5, 3) is nearer
    assert _step([(0.2, 1.0), (1.0, 5.0), (0.5, 3.0)], 4.0) == pytest.approx(0.75)


def test_without_a_bracket_the_last_two_pairs_extrapolate() -> None:
    # (1, 6) and (0.8, 5): 5 ms per unit of scale; live 4 -> 0.6
    assert _step([(1.0, 6.0), (0.8, 5.0)], 4.0) == pytest.approx(0.6)
    # equal DES means: back to the two-hop step from the last pair
    assert _step([(1.0, 5.0), (0.8, 5.0)], 4.0) == pytest.approx(0.3)


def test_a_kinds_cpu_first_scales_its_side_part_by_the_cpu_ratio() -> None:
    # live 0.45 cores, DES 0.30 at scale 1 -> 1.5; bounded by [0, SIDE_MAX]
    k = _first("server", 1.0, 0.45, 0.30, MEAN)
    assert k == pytest.approx(1.5)
    assert _next_scale([(1.0, 0.30)], 0.45, k, 0.0, SIDE_MAX) == pytest.approx(1.5)
    assert _next_scale([(1.0, 0.01)], 0.45, _first("host", 1.0, 0.45, 0.01, MEAN), 0.0,
                       SIDE_MAX) == SIDE_MAX
    assert _first("host", 2.0, 0.45, 0.0, MEAN) == 2.0  # no DES CPU: stays


def test_live_cpu_is_the_server_and_the_busiest_host_mean_over_methods(tmp_path: Path) -> None:
    cols = "method,process,pid,idle_s,idle_cpu_s,window_s,cpu_s,messages"
    rows = ["none,server,1,1,0,2.0,1.0,10", "none,host0,2,1,0,2.0,0.4,5",
            "none,host1,3,1,0,2.0,0.6,5", "none,broker,4,1,0,2.0,0.2,20",
            "bides,server,5,1,0,4.0,1.0,10", "bides,host0,6,1,0,4.0,0.8,5",
            "bides,host1,7,1,0,4.0,0.4,5", "bides,broker,8,1,0,4.0,0.2,20"]
    (tmp_path / "cpu.csv").write_text("\n".join([cols, *rows]) + "\n")
    # server 0.5 and 0.25 cores -> 0.375; busiest host 0.3 and 0.2 -> 0.25
    assert _live_cpu(tmp_path) == {"server": pytest.approx(0.375), "host": pytest.approx(0.25)}
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _live_cpu(empty) == {}  # no cpu.csv: nothing to match


def test_a_pair_counts_only_while_the_other_scales_stay_where_they_are() -> None:
    """Round 1 at scales (hop 1.0, server 1.0), round 2 (0.5, 1.5), round 3 (0.6, 1.51):
    now at (0.6, 1.52), the hop's pairs are those of the rounds whose server scale was
    within 2 % of 1.52 (rounds 2 and 3), and the server's those whose hop scale was
    within 2 % of 0.6 (round 3 only). On ``s15``'s calibration run the stale pairs of
    rounds with other side parts held the up hop 9 % off live for five rounds."""
    tried = [({"hop_up": 1.0, "server": 1.0}, {"hop_up": 4.3, "server": 0.38}),
             ({"hop_up": 0.5, "server": 1.5}, {"hop_up": 2.9, "server": 0.41}),
             ({"hop_up": 0.6, "server": 1.51}, {"hop_up": 3.5, "server": 0.43})]
    now = {"hop_up": 0.6, "server": 1.52}
    assert _pairs(tried, now, "hop_up") == [(0.5, 2.9), (0.6, 3.5)]
    assert _pairs(tried, now, "server") == [(1.51, 0.43)]


def _bundled_cal(tmp: Path) -> Scenario:
    """A calibrated scenario (N = 4 on 2 hosts, one method, 1 s) whose state hops are
    empirical samples: 1 ms and 3 ms up to the broker and on to the server."""
    hop, trig = tmp / "hop_up.txt", tmp / "hop_down.txt"
    np.savetxt(hop, [0.001, 0.003])
    np.savetxt(trig, [0.0002])
    sc = load(None, ["nodes=4", "hosts=2", "duration=1.0", "warmup=0.5",
                     'methods=["none"]'])
    up, down = Dist(dist="empirical", file=str(hop)), Dist(dist="empirical", file=str(trig))
    net = sc.net
    return replace(sc, net=replace(
        net, host_link=replace(net.host_link, latency=up, latency_down=down),
        server_link=replace(net.server_link, latency=down, latency_down=up)))


def test_the_bundled_run_is_matched_by_scaling_the_state_hops(tmp_path: Path) -> None:
    """The live run's pooled state latency is the DES's own at 1.5 times the state hops:
    the match finds the factor within its tolerance (the hops are pure delays, so the
    latency is linear in it), at that run's nodes; a run without a live
    latency is skipped, saying so."""
    cal = _bundled_cal(tmp_path)
    rep = {"delivery_service_per_client_s": 2e-5}
    want = prepare(cal, {**rep, "bundle_hop_scale": 1.5, "bundle_hop_nodes": 4.0},
                   [], bundle=True, samples_dir=tmp_path / "w")
    live = float(run_method(want, "none")["metrics"]["latency_state_mean"])
    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.json").write_text(json.dumps(
        {"methods": {"none": {"latency_state_mean": live}}}))
    got = match_bundled(cal, {**rep, "bundle_hop_scale": 9.0}, cal, run, "run")
    assert got["bundle_hop_nodes"] == 4.0 and got["bundle_hop_run"] == "run"
    assert abs(got["bundle_hop_des_ms"] - live) <= MATCH_TOL * live
    assert got["bundle_hop_scale"] == pytest.approx(1.5, abs=0.1)
    assert 2 <= got["bundle_hop_rounds"] <= 4 and "bundle_hop_warning" not in got
    # two runs of the setting: the target is their mean (0.8 and 1.2 times the latency)
    twin = tmp_path / "twin"
    twin.mkdir()
    for d, f in ((run, 0.8), (twin, 1.2)):
        (d / "summary.json").write_text(json.dumps(
            {"methods": {"none": {"latency_state_mean": f * live}}}))
    two = match_bundled(cal, rep, cal, [run, twin], "run, twin")
    assert two["bundle_hop_runs"] == 2.0 and two["bundle_hop_live_ms"] == pytest.approx(live)
    assert two["bundle_hop_scale"] == pytest.approx(1.5, abs=0.1)
    one = match_bundled(cal, rep, cal, [run], "run")
    assert one["bundle_hop_live_ms"] == pytest.approx(0.8 * live)
    assert one["bundle_hop_scale"] < two["bundle_hop_scale"] - 0.2
    # a live latency no scale within K_MAX reaches: the match says so
    (run / "summary.json").write_text(json.dumps(
        {"methods": {"none": {"latency_state_mean": 100.0 * live}}}))
    far = match_bundled(cal, rep, cal, run, "run")
    assert far["bundle_hop_scale"] == K_MAX and "matched only to" in far["bundle_hop_warning"]
    (run / "summary.json").write_text(json.dumps({"methods": {"none": {}}}))
    assert "skipped" in match_bundled(cal, rep, cal, run, "run")["bundle_hop_match"]
